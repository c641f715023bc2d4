"""The interpolator: exact sines on a circle at constant feed, every axis within its limits,
exact stops at block ends."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twin_cosim.contour.gcode import Motion, parse_program
from twin_cosim.contour.interpolation import (
    InterpolationError,
    axis_derivatives,
    feed_warnings,
    jerk_limited,
    plan_block,
    plan_blocks,
    plan_program,
    ramp_distance,
    reachable_speed,
)
from twin_cosim.contour.path import Arc, Line, distance_to_path
from twin_cosim.scenario.machine import AxisLimits

LIMITS = {
    "X": AxisLimits(0.25, 2.0, 40.0),
    "Y": AxisLimits(0.1, 0.5, 10.0),
}


def test_a_circle_at_constant_feed_gives_exact_sines_on_each_axis():
    radius, feed = 0.01, 1000 / 60e3
    arc = Arc((0.0, 0.0), radius, 0.0, 4 * math.pi)
    motion = plan_blocks([Motion(arc, feed, 1)], (radius, 0.0, 0.0), LIMITS, 0.004, 0.0)
    x, y = motion.samples[:, 0], motion.samples[:, 1]
    t = np.arange(len(x)) * 0.004
    angle = np.unwrap(np.arctan2(y, x))
    cruising = (t > 0.3) & (t < motion.end_time - 0.3)
    rate = np.diff(angle[cruising]) / 0.004
    assert np.allclose(rate, feed / radius, rtol=1e-9)  # constant feed: angular rate v / R
    phase = angle[cruising][0] - feed / radius * t[cruising][0]
    expected = radius * np.cos(phase + feed / radius * t[cruising])
    assert np.max(np.abs(x[cruising] - expected)) < 1e-12
    assert np.allclose(np.hypot(x, y), radius, atol=1e-15)


@pytest.mark.parametrize(
    "element",
    [
        Line((0.0, 0.0, 0.0), (0.05, 0.02, 0.0)),
        Line((0.0, 0.0, 0.0), (0.0, -0.03, 0.0)),
        Arc((0.0, 0.0), 0.002, 0.3, -5.0),
        Arc((0.0, 0.0), 0.05, 0.0, 2.0),
    ],
)
@pytest.mark.parametrize("feed", [None, 0.05, 0.2])
def test_every_axis_stays_within_its_limits(element, feed):
    profile = plan_block(element, feed, LIMITS)
    tau = np.linspace(0.0, profile.duration, 20001)
    velocity, acceleration, jerk = np.abs(axis_derivatives(element, profile, tau))
    for name, column in (("X", 0), ("Y", 1)):
        limit = LIMITS[name]
        assert velocity[:, column].max() <= limit.velocity * (1 + 1e-6)
        assert acceleration[:, column].max() <= limit.acceleration * (1 + 1e-6)
        assert jerk[:, column].max() <= limit.jerk * (1 + 1e-6)
    if feed is not None:
        assert profile.v.max() <= feed * (1 + 1e-12)


def test_the_arc_speed_is_the_feed_where_the_limits_allow_it():
    arc = Arc((0.0, 0.0), 0.01, 0.0, 4 * math.pi)
    assert plan_block(arc, 0.02, LIMITS).v.max() == pytest.approx(0.02, rel=1e-12)
    small = plan_block(Arc((0.0, 0.0), 0.0005, 0.0, 4 * math.pi), 0.1, LIMITS).v.max()
    assert small < 0.1  # the centripetal acceleration caps it
    assert small**2 / 0.0005 <= 0.5 * LIMITS["Y"].acceleration * (1 + 1e-9)


def test_exact_stop_at_block_ends_and_dwells_hold_the_position():
    program = parse_program("G01 X10 F3000\nG04 P0.2\nG01 Y5\n")
    motion = plan_program(program, LIMITS, 0.004, 0.1)
    x, y = motion.samples[:, 0], motion.samples[:, 1]
    t = np.arange(len(x)) * 0.004
    first_end = t[np.argmax(x >= 0.01 - 1e-15)]
    holding = (t >= first_end) & (t <= first_end + 0.2 - 0.004)  # the dwell, sampled
    assert np.all(x[holding] == 0.01) and np.all(y[holding] == 0.0)
    assert np.all(np.diff(y[t <= first_end + 0.2 - 0.004]) == 0.0)  # Y waits for the dwell
    assert np.allclose(motion.samples[-1], [0.01, 0.005])
    assert motion.end_time + 0.1 == pytest.approx(t[-1], abs=0.004)


def _chords(radius_mm: float, count: int, turn: float, feed: float, mode: str) -> str:
    """A CAM program's chords of an arc about the origin (0.1 um digits), after a rapid."""
    lines = [mode, "G17 G21 G90", f"G00 X{radius_mm:.4f} Y0", f"G01 F{feed:g}"]
    for k in range(1, count + 1):
        a = turn * k / count
        lines.append(f"X{radius_mm * math.cos(a):.4f} Y{radius_mm * math.sin(a):.4f}")
    return "\n".join(lines) + "\nM30\n"


def _deviation(motion) -> np.ndarray:
    """Distance (m) of each sampled reference to the programmed path."""
    points = np.column_stack((motion.samples, np.zeros(len(motion.samples))))
    return distance_to_path(motion.elements, points)


@pytest.mark.parametrize("tolerance_mm", [0.005, 0.02])
def test_blending_leaves_the_programmed_path_by_at_most_the_tolerance(tolerance_mm):
    text = _chords(10.0, 300, math.pi / 2, 1000, f"G64 P{tolerance_mm}")
    text = text.replace("M30", "G01 X-5 Y10\nG01 X-5 Y-3\nM30")  # and sharp corners
    motion = plan_program(parse_program(text), LIMITS, 0.004, 0.0)
    assert _deviation(motion).max() <= tolerance_mm * 1e-3 * (1 + 1e-9)
    assert _deviation(motion).max() > 0.2 * tolerance_mm * 1e-3  # corners are cut


def test_blending_keeps_every_axis_within_its_limits_at_the_interpolation_period():
    """Velocity, acceleration and jerk from the 4 ms samples' differences (what the position
    loop interpolates): within each axis' limits (a step at a join counts over one period)."""
    text = _chords(5.0, 400, math.pi, 2000, "G64 P0.005").replace("M30", "G01 X-8 Y4\nM30")
    period = 0.004
    motion = plan_program(parse_program(text), LIMITS, period, 0.0)
    for k, name in enumerate(("X", "Y")):
        x = motion.samples[:, k]
        velocity = np.diff(x) / period
        acceleration = np.diff(x, 2) / period**2
        jerk = np.diff(x, 3) / period**3
        limit = LIMITS[name]
        assert np.abs(velocity).max() <= limit.velocity * 1.001
        assert np.abs(acceleration).max() <= limit.acceleration * 1.02
        assert np.abs(jerk).max() <= limit.jerk * 1.02


def test_blending_keeps_the_feed_along_chords_and_is_many_times_faster_than_exact_stop():
    blended = plan_program(
        parse_program(_chords(10.0, 200, math.pi / 2, 1000, "G64 P0.005")), LIMITS, 0.004, 0.0
    )
    stopping = plan_program(
        parse_program(_chords(10.0, 200, math.pi / 2, 1000, "G61")), LIMITS, 0.004, 0.0
    )
    chords = [f for f in blended.feeds if f.programmed is not None]
    assert max(f.reached for f in chords) == pytest.approx(1000 / 60e3, rel=1e-9)
    assert stopping.end_time > 3 * blended.end_time
    assert feed_warnings(blended) == []
    assert (
        "G61" in feed_warnings(stopping)[0]
        and "lines 5-204 (200 blocks)" in feed_warnings(stopping)[0]
    )


def test_the_look_ahead_lets_the_machine_stop_within_its_window():
    text = _chords(50.0, 400, math.pi / 2, 12000, "G64 P0.005 Q0")  # every chord a block
    far = plan_program(parse_program(text), LIMITS, 0.004, 0.0, look_ahead=200)
    near = plan_program(parse_program(text), LIMITS, 0.004, 0.0, look_ahead=2)
    top_far = max(f.reached for f in far.feeds if f.programmed)  # the chords
    top_near = max(f.reached for f in near.feeds if f.programmed)
    assert top_near < top_far / 2
    chord = 2 * math.pi * 0.05 / 4 / 400  # m
    least = (LIMITS["Y"].acceleration / 2, LIMITS["Y"].jerk / 2)  # the arcs' share, Y the least
    # from a chord's start, the machine stops within it and the two blocks after it
    assert top_near <= reachable_speed(0.0, 3 * chord, *least) * (1 + 1e-9)


@pytest.mark.parametrize(("start", "end"), [(0.0, 0.02), (0.01, 0.005), (0.03, 0.0)])
def test_ramp_distance_is_ruckigs_and_reachable_speed_its_inverse(start, end):
    profile = jerk_limited(1.0, max(start, end) * 1.0001, 0.5, 10.0, start, end)
    # a length just long enough: ruckig changes the speed and covers it with no cruise
    length = ramp_distance(start, end, 0.5, 10.0)
    tight = jerk_limited(length, 1.0, 0.5, 10.0, start, end)
    assert tight.evaluate(np.array([tight.duration]))[0][0] == pytest.approx(length, rel=1e-9)
    assert reachable_speed(min(start, end), length, 0.5, 10.0) == pytest.approx(
        max(start, end), rel=1e-9
    )
    assert profile.duration > 0


def test_the_feed_override_scales_the_feeds_but_not_the_rapids():
    program = parse_program("G01 X100 F600\nG00 X0\n")
    full = plan_program(program, LIMITS, 0.004, 0.0)
    half = plan_program(program, LIMITS, 0.004, 0.0, feed_override=0.5)
    assert half.feeds[0].reached == pytest.approx(full.feeds[0].reached / 2, rel=1e-9)
    assert half.feeds[1].reached == pytest.approx(full.feeds[1].reached, rel=1e-9)


def test_a_feed_the_axes_do_not_allow_is_said():
    motion = plan_program(parse_program("G01 X100 Y0 F100000\n"), LIMITS, 0.004, 0.0)
    (warning,) = feed_warnings(motion)
    assert warning.startswith("line 1: feed 15000 mm/min reached of 100000 mm/min programmed")
    assert "axis X's velocity limit" in warning


def test_a_program_leaving_the_travel_is_refused_naming_line_axis_and_limit():
    travel = {name: dataclasses.replace(lim, travel=(-0.1, 0.1)) for name, lim in LIMITS.items()}
    inside = "G01 X80 F1000\nG03 X80 Y40 I0 J20\n"  # the arc touches X = 100 mm
    plan_program(parse_program(inside, "part.nc"), travel, 0.004, 0.0)
    bulging = "G01 X80 F1000\nG03 X80 Y50 I0 J25\n"  # both ends inside, the arc reaches 105
    with pytest.raises(InterpolationError) as error:
        plan_program(parse_program(bulging, "part.nc"), travel, 0.004, 0.0)
    assert str(error.value) == (
        "part.nc: line 2: the path reaches X = 105 mm, beyond axis X's travel [-100, 100] mm "
        "(axes.X.limits.travel)"
    )
    low = "G01 X10 F1000\nG01 Y-100.5\n"
    with pytest.raises(InterpolationError, match=r"line 2: the path reaches Y = -100.5 mm"):
        plan_program(parse_program(low, "part.nc"), travel, 0.004, 0.0)
