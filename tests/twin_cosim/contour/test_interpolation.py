"""The interpolator: exact sines on a circle at constant feed, every axis within its limits,
exact stops at block ends."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.contour.gcode import Motion, parse_program
from twin_cosim.contour.interpolation import (
    axis_derivatives,
    plan_block,
    plan_blocks,
    plan_program,
)
from twin_cosim.contour.path import Arc, Line
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
