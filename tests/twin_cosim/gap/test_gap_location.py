"""Where along the axis: spans of concentrated residual, by direction."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.location import along_axis
from twin_cosim.gap.regimes import CONSTANT_VELOCITY, REVERSAL
from twin_cosim.gap.residuals import Residuals
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


def test_a_defect_in_one_direction_is_named_with_it():
    spans = along_axis(strokes((10.0, 11.0), directions=(-1,)), 1e-8, 1e-3, SETTINGS)
    assert spans[0].direction == -1
    assert 9.0 <= spans[0].from_mm and spans[0].to_mm <= 12.0


def test_an_even_residual_names_no_span_and_reversals_are_not_places():
    assert along_axis(strokes(None), 1e-8, 1e-3, SETTINGS) == []
