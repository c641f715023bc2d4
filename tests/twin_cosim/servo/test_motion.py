"""The test motions: exact pieces of constant acceleration, levels held where they say."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.servo.motion import LEVEL_RAMP_S, START_ACCELERATION, speed_levels, step_grid

PERIOD = 250e-6


def test_levels_hold_their_speed_and_the_position_integrates_it():
    speeds = [0.03, 0.01, -0.002]
    grid, levels = speed_levels(speeds, 0.2, PERIOD, start=0.1)
    assert grid.position[0] == 0.1 and grid.velocity[0] == 0.0
    for level, speed in zip(levels, speeds, strict=True):
        assert level.speed == speed
        np.testing.assert_allclose(grid.velocity[level.steady], speed, rtol=1e-12)
        np.testing.assert_allclose(grid.acceleration[level.steady][:-1], 0.0, atol=1e-12)
    # x(k+1) - x(k) = v(k) T + a(k) T^2 / 2: pieces of constant acceleration, exact
    step = grid.velocity[:-1] * PERIOD + 0.5 * grid.acceleration[:-1] * PERIOD**2
    np.testing.assert_allclose(np.diff(grid.position), step, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(np.diff(grid.velocity), grid.acceleration[:-1] * PERIOD, atol=1e-15)
    assert np.max(np.abs(grid.acceleration)) == pytest.approx(START_ACCELERATION)
    ramp = (0.03 - 0.01) / LEVEL_RAMP_S  # the second level's ramp
    assert np.min(grid.acceleration) == pytest.approx(-ramp, rel=1e-9)


def test_a_step_test_stands_still():
    grid = step_grid(0.5, PERIOD, 0.02)
    assert len(grid.position) == 2001 and np.all(grid.position == 0.02)
    assert not grid.velocity.any() and not grid.acceleration.any()
