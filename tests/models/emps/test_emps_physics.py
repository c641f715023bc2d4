"""The emps plant against mechanics: acceleration, friction, delay, encoder, velocity estimate."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_build.build import build_fmu
from twin_cosim.plant import Plant, PlantError

M, FV, FC, OFFSET, GAIN = 95.1089, 203.5034, 20.3935, -3.1648, 35.15065188
LEAD = 3.978873577297384e-4


@pytest.fixture(scope="module")
def emps():
    with Plant(build_fmu("emps")) as plant:
        yield plant


def step(
    plant: Plant,
    commands,
    parameters,
    h=1e-3,
    outputs=("load_position", "load_speed", "motor_speed", "force"),
):
    plant.start_run(parameters)
    vr_in = [plant.value_reference("current_cmd")]
    vr_out = [plant.value_reference(n) for n in outputs]
    values = []
    for k, u in enumerate(commands):
        plant.fmu.setReal(vr_in, [float(u)])
        plant.fmu.doStep(k * h, h)
        values.append(plant.fmu.getReal(vr_out))
    return {name: np.array(values)[:, i] for i, name in enumerate(outputs)}


def test_constant_force_reaches_the_viscous_speed(emps):
    u = 3.0  # V: 105 N against 20.4 N of Coulomb friction
    out = step(emps, np.full(6000, u), {"position_resolution": 0.0})
    terminal = (GAIN * u - FC - OFFSET) / FV  # m/s, where viscous friction takes the rest
    assert out["load_speed"][-1] == pytest.approx(terminal, rel=1e-3)
    # early on, the acceleration is (F - Fc - offset)/M
    assert out["load_speed"][10] == pytest.approx((GAIN * u - FC - OFFSET) / M * 0.010, rel=0.05)


def test_force_below_breakaway_holds_the_axis(emps):
    out = step(emps, np.full(500, (FC + OFFSET) / GAIN * 0.9), {"position_resolution": 0.0})
    assert np.all(out["load_position"] == 0.0)


def test_command_acts_one_step_late_by_default(emps):
    out = step(emps, [1.0, 2.0, 3.0], {})
    assert list(out["force"]) == pytest.approx([0.0, GAIN * 1.0, GAIN * 2.0])
    out = step(emps, [1.0, 2.0, 3.0], {"dead_time_steps": 0})
    assert list(out["force"]) == pytest.approx([GAIN * 1.0, GAIN * 2.0, GAIN * 3.0])


def test_encoder_grid_and_velocity_estimate(emps):
    out = step(emps, np.full(400, 3.0), {})
    x = out["load_position"]
    assert np.max(np.abs(x / 5e-8 - np.round(x / 5e-8))) < 1e-6
    expected = (x[2:] - x[:-2]) / (2 * 1e-3) / LEAD  # difference of two-sample averages
    np.testing.assert_allclose(out["motor_speed"][2:], expected, rtol=1e-9, atol=1e-9)


def test_asymmetric_friction_levels(emps):
    a, b = -0.25, -36.9
    for sign in (1.0, -1.0):
        out = step(
            emps,
            np.full(6000, 3.0 * sign),
            {"coulomb_asymmetry": a, "viscous_asymmetry": b, "position_resolution": 0.0},
        )
        terminal = (GAIN * 3.0 * sign - (FC + a * sign) * sign - OFFSET) / (FV + b * sign)
        assert out["load_speed"][-1] == pytest.approx(terminal, rel=1e-3)


def test_bad_values_are_refused(emps):
    with pytest.raises(PlantError, match="second_mass"):
        emps.start_run({"second_mass": 200.0})
    with pytest.raises(PlantError, match="asymmetry makes a friction level negative"):
        emps.start_run({"coulomb_asymmetry": 30.0})


# ---------------------------------------------------------------- variable communication steps

VARIABLE_STEPS = np.array([1.0e-3, 0.3e-3, 0.7e-3, 1.3e-3, 0.45e-3, 0.25e-3])  # s, repeated


def step_times(total: float, pattern: np.ndarray) -> np.ndarray:
    """Communication points 0 = t_0 < t_1 < ... covering ``total`` s with the step pattern."""
    steps = np.resize(pattern, int(np.ceil(total / pattern.mean())) + len(pattern))
    times = np.concatenate([[0.0], np.cumsum(steps)])
    return times[: np.searchsorted(times, total) + 1]


def run_at(plant: Plant, times: np.ndarray, command, parameters, outputs):
    """Step from times[k] to times[k + 1] with command(times[k]) set before each step."""
    plant.start_run(parameters)
    vr_in = [plant.value_reference("current_cmd")]
    vr_out = [plant.value_reference(n) for n in outputs]
    values = []
    for t, t_next in zip(times[:-1], times[1:], strict=True):
        plant.fmu.setReal(vr_in, [command(t)])
        plant.fmu.doStep(t, t_next - t)
        values.append(plant.fmu.getReal(vr_out))
    return {name: np.array(values)[:, i] for i, name in enumerate(outputs)}


def linear_axis(times: np.ndarray, force_changes: list[tuple[float, float]]):
    """Position (m) and speed (m/s) at ``times`` of M dv/dt = F(t) - Fv v - offset from rest at
    0 without Coulomb friction; F is piecewise constant, (time s, force N) from each time on."""
    lam = FV / M
    x = np.zeros_like(times)
    v = np.zeros_like(times)
    breaks = [(0.0, 0.0), *force_changes]
    for i, t in enumerate(times):
        position = speed = 0.0
        for j, (t0, force) in enumerate(breaks):
            t1 = min(t, breaks[j + 1][0] if j + 1 < len(breaks) else np.inf)
            if t1 <= t0:
                break
            a = (force - OFFSET) / M
            decay = np.exp(-lam * (t1 - t0))
            position += a / lam * (t1 - t0) + (speed - a / lam) * (1 - decay) / lam
            speed = a / lam + (speed - a / lam) * decay
        x[i], v[i] = position, speed
    return x, v


@pytest.mark.parametrize("pattern", [np.array([1e-3]), VARIABLE_STEPS], ids=["1ms", "variable"])
def test_dead_time_in_seconds_and_speed_estimate_at_any_step(emps, pattern):
    """Analytic answer of the linear axis (Coulomb friction off): the command acts 3 ms late
    whatever the steps, and the speed estimate is (q0 - q2) / (t0 - t2) of the true positions."""
    times = step_times(0.06, pattern)
    switch = times[np.searchsorted(times, 0.02)]  # first communication point >= 20 ms
    out = run_at(
        emps,
        times,
        lambda t: 3.0 if t < switch else 2.0,
        {"coulomb_friction": 0.0, "position_resolution": 0.0, "dead_time_steps": 3},
        ("position_true", "load_speed", "motor_speed", "force"),
    )
    dead_time = 3 * 1e-3
    x, v = linear_axis(times, [(dead_time, GAIN * 3.0), (switch + dead_time, GAIN * 2.0)])
    np.testing.assert_allclose(out["position_true"], x[1:], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(out["load_speed"], v[1:], rtol=1e-9, atol=1e-15)
    estimate = (x[3:] - x[1:-2]) / (times[3:] - times[1:-2]) / LEAD
    np.testing.assert_allclose(out["motor_speed"][2:], estimate, rtol=1e-8)
    acting = np.where(times[1:] > switch + dead_time + 1e-12, 2.0, 3.0)
    np.testing.assert_allclose(out["force"], np.where(times[1:] > dead_time, GAIN * acting, 0.0))


def test_speed_estimate_after_a_short_step_is_the_speed(emps):
    """At the terminal speed, one short step among 1 ms steps leaves the estimate on the speed."""
    times = np.concatenate([np.arange(0, 6.0, 1e-3), 6.0 + np.array([0.1e-3, 1.1e-3, 2.1e-3])])
    out = run_at(
        emps, times, lambda t: 3.0, {"position_resolution": 0.0}, ("motor_speed", "load_speed")
    )
    terminal = (GAIN * 3.0 - FC - OFFSET) / FV  # m/s
    np.testing.assert_allclose(out["motor_speed"][-3:] * LEAD, terminal, rtol=1e-5)
    np.testing.assert_allclose(out["load_speed"][-3:], terminal, rtol=1e-5)
