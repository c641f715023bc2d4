"""Each piece of the P-PI cascade on its own, then each compensator's effect on the twin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim import controller as c
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.controller_set import FINE_TUNE
from twin_cosim.cosim import AxisRun, run_axes
from twin_cosim.metrics import compute_metrics
from twin_cosim.reference import Dwell, Ramp, ReferenceGrid, interpolate, sample_segments


def run_axis(plant, grid, tuned, settings, plant_parameters=None, fast=True):
    """One axis on the master, its record per position-loop sample."""
    axis = AxisRun("X", plant, grid, tuned, settings, plant_parameters or {})
    return run_axes([axis], fast)["X"].position_loop


SETTINGS = ControllerSettings()
TRAVEL = SETTINGS.travel_per_rad


def vectors(tuned=FINE_TUNE, **settings):
    return c.parameter_vector(tuned, ControllerSettings(**settings)), c.initial_state()


def test_position_gain_and_velocity_feedforward():
    p, s = vectors(ff_velocity=0.0, ff_acceleration=0.0, friction_torque=0.0)
    c.position_loop(p, s, 0.0, 10e-6, 0.0, 0.0, 4e-6)
    assert s[c.SPEED_CMD] == pytest.approx(FINE_TUNE.Kp_pos * 6e-6 / TRAVEL)
    p, s = vectors(ff_velocity=1.0, ff_acceleration=0.0, friction_torque=0.0)
    c.position_loop(p, s, 0.0, 0.0, 0.02, 0.0, 0.0)
    assert s[c.SPEED_CMD] == pytest.approx(0.02 / TRAVEL)


def test_acceleration_feedforward_is_inertia_torque():
    p, s = vectors(ff_acceleration=1.0, friction_torque=0.0)
    c.position_loop(p, s, 0.0, 0.0, 0.0, 0.5, 0.0)
    assert s[c.CURRENT_FF] == pytest.approx(
        SETTINGS.inertia * 0.5 / TRAVEL / SETTINGS.torque_constant
    )


def test_direction_relay_has_hysteresis_f_h():
    p, s = vectors()
    band = FINE_TUNE.f_H * TRAVEL  # m/s at the carriage
    c.position_loop(p, s, 0.0, 0.0, 0.9 * band, 0.0, 0.0)
    assert s[c.DIRECTION] == 0.0
    c.position_loop(p, s, 0.1, 0.0, 1.1 * band, 0.0, 0.0)
    assert (s[c.DIRECTION], s[c.FLIP_TIME]) == (1.0, 0.1)
    c.position_loop(p, s, 0.2, 0.0, -0.9 * band, 0.0, 0.0)  # inside the band: holds
    assert s[c.DIRECTION] == 1.0
    c.position_loop(p, s, 0.3, 0.0, -1.1 * band, 0.0, 0.0)
    assert (s[c.DIRECTION], s[c.FLIP_TIME]) == (-1.0, 0.3)


def test_friction_compensation_follows_the_direction():
    p, s = vectors(ff_acceleration=0.0)
    c.position_loop(p, s, 0.0, 0.0, 0.01, 0.0, 0.0)
    assert s[c.CURRENT_FF] == pytest.approx(SETTINGS.friction_torque / SETTINGS.torque_constant)
    c.position_loop(p, s, 0.1, 0.0, -0.01, 0.0, 0.0)
    assert s[c.CURRENT_FF] == pytest.approx(-SETTINGS.friction_torque / SETTINGS.torque_constant)


def test_reversal_pulse_decays_with_pp3():
    tuned = TunedParameters(1.0, 1.0, 0.0, PP2=2.0, PP3=0.01, f_H=0.1)
    p, s = vectors(tuned, ff_velocity=0.0, ff_acceleration=0.0, friction_torque=0.0)
    c.position_loop(p, s, 0.5, 0.0, -0.01, 0.0, 0.0)  # flips to -1 at t = 0.5 s
    for dt in (0.0, 0.01, 0.03):
        current = c.speed_loop(p, s, 0.5 + dt, 0.0)  # Kp_vel = 1 A/(rad/s), no integral
        assert current == pytest.approx(-2.0 * math.exp(-dt / 0.01))


def test_speed_pi_integrates_per_sample_and_stops_at_the_limit():
    tuned = TunedParameters(1.0, 0.5, 0.01, 0.0, 0.01, 0.0)
    p, s = vectors(tuned, current_limit=2.0, friction_torque=0.0)
    s[c.SPEED_CMD] = 1.0
    currents = [c.speed_loop(p, s, k * 62.5e-6, 0.0) for k in range(3)]
    assert currents == pytest.approx([0.5 + 0.01, 0.5 + 0.02, 0.5 + 0.03])
    s[c.SPEED_CMD] = 100.0
    held = s[c.INTEGRAL]
    assert c.speed_loop(p, s, 0.0, 0.0) == 2.0
    assert s[c.INTEGRAL] == held  # anti-windup: frozen while clipped
    s[c.SPEED_CMD] = -100.0
    assert c.speed_loop(p, s, 0.0, 0.0) == -2.0


def test_invalid_parameters_are_refused():
    with pytest.raises(ValueError, match="Kp_pos must be > 0"):
        TunedParameters(0.0, 0.3, 0.008, 0.7, 0.008, 0.13)
    with pytest.raises(ValueError, match="PP2 must be finite"):
        TunedParameters(66.0, 0.3, 0.008, math.nan, 0.008, 0.13)
    with pytest.raises(ValueError, match="whole multiple"):
        ControllerSettings(position_period=250e-6, speed_period=60e-6)


# ---------------------------------------------------------------- effects on the twin


def grid_of(segments) -> ReferenceGrid:
    return interpolate(sample_segments(segments, 0.004), 0.004, 250e-6)


REVERSALS = grid_of(
    [
        Dwell(0.2),
        Ramp(0.005, 0.02, 0.6),
        Ramp(-0.005, 0.02, 1.0),
        Ramp(0.0, 0.02, 0.4),
        Dwell(0.2),
    ]
)


def epk(plant, tuned=FINE_TUNE, grid=REVERSALS, plant_parameters=None, **settings):
    record = run_axis(plant, grid, tuned, ControllerSettings(**settings), plant_parameters)
    return compute_metrics(record).E_pk_um


def test_friction_compensation_lowers_the_reversal_peak(plant):
    assert epk(plant) < 0.8 * epk(plant, friction_torque=0.0)


def test_reversal_pulse_lowers_the_reversal_peak(plant):
    no_pulse = TunedParameters(**{**FINE_TUNE.as_dict(), "PP2": 0.0})
    pulse = TunedParameters(**{**FINE_TUNE.as_dict(), "PP2": 2.0})
    assert epk(plant, pulse) < 0.9 * epk(plant, no_pulse)


def test_velocity_feedforward_removes_the_following_error(plant):
    cruise = grid_of([Dwell(0.1), Ramp(0.02, 0.2, 0.6), Ramp(0.0, 0.2, 0.2), Dwell(0.1)])
    linear = {"backlash": 0.0, "coulomb_friction": 0.0}
    without = run_axis(
        plant, cruise, FINE_TUNE, ControllerSettings(ff_velocity=0.0, friction_torque=0.0), linear
    )
    with_ff = run_axis(plant, cruise, FINE_TUNE, ControllerSettings(friction_torque=0.0), linear)
    steady = (without["t"] > 0.4) & (without["t"] < 0.6)
    # Without feedforward a P position loop lags by v / Kp_pos.
    assert without["error"][steady].mean() == pytest.approx(0.02 / FINE_TUNE.Kp_pos, rel=0.02)
    assert np.abs(with_ff["error"][steady]).max() < 0.01 * 0.02 / FINE_TUNE.Kp_pos


def test_fine_tune_gives_a_well_damped_position_step(plant):
    n = 2000
    step = ReferenceGrid(
        250e-6, np.r_[np.zeros(200), np.full(n - 200, 1e-6)], np.zeros(n), np.zeros(n)
    )
    record = run_axis(
        plant,
        step,
        FINE_TUNE,
        ControllerSettings(ff_velocity=0.0, ff_acceleration=0.0, friction_torque=0.0),
        {"backlash": 0.0, "coulomb_friction": 0.0},
    )
    x = np.asarray(record["x"])
    assert x.max() < 1.05e-6  # overshoot below 5 %
    assert abs(x[-1] - 1e-6) < 0.01e-6  # settled
