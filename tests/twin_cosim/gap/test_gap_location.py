"""Where along the axis: spans of concentrated residual, by direction."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from twin_cosim.gap.data.regimes import ACCELERATION, CONSTANT_VELOCITY, REVERSAL
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.location import along_axis, locate, stroke_ends
from twin_cosim.gap.settings import DiagnosisSettings

SETTINGS = DiagnosisSettings()


def strokes(spot_mm: tuple[float, float] | None, directions=(1, -1), seed=0, reversal_at_ends=True):
    """Back-and-forth strokes over 0-40 mm with white residuals, raised inside a spot."""
    rng = np.random.default_rng(seed)
    x_out = np.linspace(0.0, 0.04, 4000)
    parts_x, parts_d = [], []
    for _ in range(3):
        parts_x += [x_out, x_out[::-1]]
        parts_d += [np.ones(4000), -np.ones(4000)]
    x, direction = np.concatenate(parts_x), np.concatenate(parts_d)
    n = len(x)
    position = rng.normal(0, 1e-8, n)
    current = rng.normal(0, 1e-3, n)
    if spot_mm is not None:
        inside = (x * 1e3 >= spot_mm[0]) & (x * 1e3 <= spot_mm[1]) & np.isin(direction, directions)
        current[inside] += 0.02 * rng.normal(0, 1, inside.sum())
    regimes = np.full(n, CONSTANT_VELOCITY)
    if reversal_at_ends:
        regimes[(x < 0.5e-3) | (x > 39.5e-3)] = REVERSAL
        current[regimes == REVERSAL] += 0.05  # a reversal residual: excluded, not a place
    return Residuals(np.arange(n) * 250e-6, position, current, regimes, np.zeros(n), x, direction)


def test_a_local_defect_is_located_within_its_span():
    spans = along_axis(strokes((21.0, 22.5)), 1e-8, 1e-3, SETTINGS)
    assert spans, "the spot was not found"
    first = spans[0]
    assert first.direction == 0
    assert first.from_mm == pytest.approx(21.0, abs=1.0)
    assert first.to_mm == pytest.approx(22.5, abs=1.0)
    assert first.energy_share > 0.8


def test_a_rotor_turns_without_travel_and_names_no_span():
    """The same concentrated residual: a carriage's span, none for a rotor's angle turned (its
    regimes and orders are still read)."""
    res = strokes((21.0, 22.5))
    carriage = locate(res, 1e-8, 1e-3, lambda angle: angle, 250e-6, SETTINGS)
    rotor = locate(res, 1e-8, 1e-3, lambda angle: angle, 250e-6, SETTINGS, travel=False)
    assert carriage.along_axis and rotor.along_axis == []
    assert rotor.position == carriage.position and rotor.current == carriage.current


def test_a_defect_in_one_direction_is_named_with_it():
    spans = along_axis(strokes((10.0, 11.0), directions=(-1,)), 1e-8, 1e-3, SETTINGS)
    assert spans[0].direction == -1
    assert 9.0 <= spans[0].from_mm and spans[0].to_mm <= 12.0


def test_an_even_residual_names_no_span_and_reversals_are_not_places():
    assert along_axis(strokes(None), 1e-8, 1e-3, SETTINGS) == []


def test_a_span_where_strokes_end_is_marked_so():
    """The residual of low speed near the ends of travel (here: the last 2.5 mm of each stroke,
    decelerating) is a span at the ends of strokes, not a tight spot; a mid-travel spot is not."""
    res = strokes((21.0, 22.5))
    ends = (res.x < 2.5e-3) | (res.x > 37.5e-3)
    regimes = np.where(ends & (res.regimes != REVERSAL), ACCELERATION, res.regimes)
    current = res.current + np.where(ends & (res.regimes != REVERSAL), 0.03, 0.0)
    slowing = dataclasses.replace(res, current=current, regimes=regimes)
    spans = along_axis(slowing, 1e-8, 1e-3, SETTINGS)
    at_ends = [s for s in spans if s.to_mm <= 3.5 or s.from_mm >= 36.5]
    assert at_ends and all(s.at_stroke_end for s in at_ends)
    middle = [s for s in spans if 20.0 <= s.from_mm <= 23.0]
    assert middle and not any(s.at_stroke_end for s in middle)


def test_stroke_ends_mark_speeding_up_and_slowing_down_inside_the_record():
    cruise, speed_change = [CONSTANT_VELOCITY], [ACCELERATION]
    regimes = np.array(cruise * 3 + speed_change * 4 + cruise * 3 + speed_change * 2 + [0] * 2)
    direction = np.array([1] * 5 + [-1] * 7 + [0] * 2)
    n, zeros = len(regimes), np.zeros(len(regimes))
    x = np.concatenate([np.linspace(0.0, 1e-3, 5), np.linspace(1e-3, 0.0, 7), [0.0, 0.0]])  # m
    res = Residuals(np.arange(n) * 1.0, zeros, zeros, regimes, zeros, x, direction)
    # the record starts moving: the first stroke's start is no speed-up
    assert (
        stroke_ends(res).tolist()
        == [False] * 3 + [True] * 4 + [False] * 3 + [True] * 2 + [False] * 2
    )
