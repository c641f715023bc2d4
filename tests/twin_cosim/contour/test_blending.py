"""Corner blending: the blend arc within the tolerance and tangent to both lines, a join's speed
from the corner and the axes' limits, the naive CAM detector's merge."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.contour.blending import (
    ARC_SHARE,
    Segments,
    blend,
    blend_radius,
    corner_speed,
    merge_straight,
)
from twin_cosim.contour.path import Arc, Line
from twin_cosim.scenario.machine import AxisLimits

LIMITS = {"X": AxisLimits(0.25, 2.0, 40.0), "Y": AxisLimits(0.25, 2.0, 40.0)}


def _corner(turn_deg: float, length: float = 0.01) -> Segments:
    """Two lines of ``length`` (m) meeting at the origin, the second turned by ``turn_deg``."""
    turn = math.radians(turn_deg)
    first = Line((-length, 0.0, 0.0), (0.0, 0.0, 0.0))
    second = Line((0.0, 0.0, 0.0), (length * math.cos(turn), length * math.sin(turn), 0.0))
    return Segments.of([first, second], [0.02, 0.02])


@pytest.mark.parametrize("turn_deg", [10.0, 45.0, 90.0, 135.0])
def test_the_blend_arc_leaves_the_corner_by_the_tolerance_and_touches_both_lines(turn_deg):
    tolerance = 5e-6
    segments, joins = blend(_corner(turn_deg), np.array([True, True]), np.full(2, tolerance))
    assert list(segments.is_line) == [True, False, True]
    arc = segments.element(1)
    theta = math.pi - math.radians(turn_deg)  # the interior angle
    expected = tolerance * math.sin(theta / 2) / (1 - math.sin(theta / 2))
    assert arc.radius == pytest.approx(expected, rel=1e-12)
    turn = np.array([math.radians(turn_deg)])
    assert blend_radius(turn, np.array([tolerance]), np.array([1.0]))[0] == pytest.approx(
        arc.radius, rel=1e-9
    )
    middle = arc.points(np.array([arc.length / 2]))[0]
    assert np.linalg.norm(middle) == pytest.approx(tolerance, rel=1e-9)  # from the corner
    # the arc starts where the first line now ends and ends where the second starts
    assert np.allclose(arc.points(np.array([0.0]))[0], segments.end[0], atol=1e-15)
    assert np.allclose(arc.end, segments.start[2], atol=1e-15)
    assert np.all(np.abs(joins.direction_step) < 1e-12)  # tangent at both ends
    assert not joins.stop.any()


def test_a_corner_between_short_lines_is_rounded_within_half_of_each():
    segments = _corner(10.0, length=2e-5)  # the tolerance alone would take more than the lines
    blended, _ = blend(segments, np.array([True, True]), np.array([1e-3, 1e-3]))
    assert blended.lengths[0] == pytest.approx(1e-5, rel=1e-9)  # half of the first line left
    arc = blended.element(1)
    assert arc.radius == pytest.approx(1e-5 / math.tan(math.radians(5.0)), rel=1e-12)


def test_exact_stop_and_a_line_turning_back_stop_at_the_corner():
    segments, joins = blend(_corner(90.0), np.array([False, False]), np.full(2, 5e-6))
    assert list(segments.is_line) == [True, True] and joins.stop.tolist() == [True]
    back, joins = blend(_corner(180.0), np.array([True, True]), np.full(2, 5e-6))
    assert len(back) == 2 and joins.stop.tolist() == [True]


def test_chords_of_an_arc_blend_into_arcs_of_about_its_radius():
    radius, count = 0.02, 50
    angles = np.linspace(0.0, math.pi / 2, count + 1)
    points = [(radius * math.cos(a), radius * math.sin(a), 0.0) for a in angles]
    chords = [Line(points[k], points[k + 1]) for k in range(count)]
    segments, joins = blend(
        Segments.of(chords, [0.02] * count), np.ones(count, bool), np.full(count, 5e-6)
    )
    arcs = ~segments.is_line
    assert arcs.sum() == count - 1
    # each arc is tangent to two chords at their middles: the circle inscribed in the chords
    inscribed = radius * math.cos(math.pi / 4 / count)
    assert np.allclose(segments.radius[arcs], inscribed, rtol=1e-9)
    assert np.all(np.abs(joins.direction_step) < 1e-9)


def test_the_speed_through_a_corner_is_that_of_its_blend_arc():
    tolerance, room = 5e-6, 0.01
    for turn_deg in (30.0, 90.0, 150.0):
        turn = math.radians(turn_deg)
        r = tolerance * math.cos(turn / 2) / (1 - math.cos(turn / 2))
        expected = min(0.25, math.sqrt(ARC_SHARE * 2.0 * r), (ARC_SHARE * 40.0 * r**2) ** (1 / 3))
        assert corner_speed(turn, tolerance, room, LIMITS) == pytest.approx(expected, rel=1e-12)
    # sharper corners are slower; a smaller acceleration slows a corner its acceleration limits
    speeds = [corner_speed(math.radians(t), 1e-3, room, LIMITS) for t in (20, 60, 120, 170)]
    assert speeds == sorted(speeds, reverse=True)
    gentle = math.radians(5.0)  # r about 10 mm: acceleration-limited at these limits
    slow = {name: AxisLimits(0.25, 0.5, 400.0) for name in LIMITS}
    fast = {name: AxisLimits(0.25, 2.0, 400.0) for name in LIMITS}
    ratio = corner_speed(gentle, 1e-5, 1.0, fast) / corner_speed(gentle, 1e-5, 1.0, slow)
    assert ratio == pytest.approx(2.0, rel=1e-9)  # sqrt(a r)


def test_a_join_from_a_line_into_an_arc_passes_at_the_speed_of_its_acceleration_step():
    line = Line((-0.01, 0.0, 0.0), (0.0, 0.0, 0.0))
    arc = Arc((0.0, 0.005), 0.005, -math.pi / 2, math.pi / 2)  # tangent, centre along +Y
    _, joins = blend(Segments.of([line, arc], [None, None]), np.ones(2, bool), np.full(2, 1e-5))
    period = 0.004
    # only Y sees the step of the centripetal acceleration v^2/R: v^2 / R <= j T
    expected = math.sqrt(40.0 * period * 0.005)
    assert joins.speed_limits(LIMITS, period)[0] == pytest.approx(expected, rel=1e-9)


def test_the_naive_cam_detector_merges_chords_whose_corners_lie_within_q():
    radius, count = 0.01, 400
    angles = np.linspace(0.0, math.pi / 2, count + 1)
    rounded = np.round(np.column_stack((radius * np.cos(angles), radius * np.sin(angles))), 7)
    points = [(x, y, 0.0) for x, y in rounded]  # a CAM program's 0.1 um digits
    chords = Segments.of([Line(points[k], points[k + 1]) for k in range(count)], [0.02] * count)
    q = 2.5e-6
    merged, last = merge_straight(chords, np.ones(count - 1, bool), np.full(count, q))
    assert len(merged) < count / 10 and last[-1] == count - 1
    first = np.concatenate(([0], last[:-1] + 1))
    for k, (a, b) in enumerate(zip(first, last, strict=True)):
        line = merged.element(k)
        corners = np.array(points[a + 1 : b + 1])
        assert np.all(line.distance(corners) <= q * (1 + 1e-9))
    # a merged line's length is about that of a chord whose sagitta is Q
    assert np.median(merged.lengths) == pytest.approx(math.sqrt(8 * radius * q), rel=0.25)
    alone, _ = merge_straight(chords, np.ones(count - 1, bool), np.zeros(count))
    assert len(alone) == count  # Q = 0: none merged
