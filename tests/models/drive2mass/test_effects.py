"""drive2mass effect blocks against physics: each block's equation, checked on the outputs.

The blocks are off by default; every test switches one on and compares the simulated outputs with
mechanics or with the block's defining equation evaluated on other outputs, never with an earlier
run. The last tests check the refusal of bad values and that explicit defaults change nothing.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from twin_cosim.cosim import run_scenario
from twin_cosim.plant import PlantError
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import load_scenario

J_M, J_L = 2.9e-4, 4.2e-4  # kg.m2, Table 1
K_T, F_C = 0.74, 0.625  # N.m/A, N.m
CARD = plant_model("drive2mass")
GEAR = CARD.motor_per_screw(CARD.start_values())  # motor revolutions per leadscrew revolution
TRAVEL = CARD.drive_facts()["travel_per_rad"]  # m per motor rad
W_01 = 2 * math.pi * 70.0  # rad/s
STIFFNESS = J_L * W_01**2  # N.m/rad, eq. (1)
H = CARD.drive_facts()["speed_period"]  # s, the twin's speed-loop period
LOSSLESS = {"backlash": 0.0, "coulomb_friction": 0.0, "viscous_friction": 0.0, "damping_ratio": 0.0}
SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml"

# Every effect parameter at its contract default.
EFFECT_DEFAULTS = {
    "stribeck_friction": 0.0,
    "stribeck_speed": 0.1,
    "coulomb_asymmetry": 0.0,
    "position_friction_amplitude": 0.0,
    "position_friction_order": 1.0,
    "position_friction_phase": 0.0,
    "lugre_stiffness": 0.0,
    "lugre_damping": 0.0,
    "pitch_error_linear": 0.0,
    "pitch_error_amplitude_1": 0.0,
    "pitch_error_phase_1": 0.0,
    "pitch_error_amplitude_2": 0.0,
    "pitch_error_phase_2": 0.0,
    "pitch_error_amplitude_3": 0.0,
    "pitch_error_phase_3": 0.0,
    "position_resolution": 0.0,
    "thermal_expansion_rate": 0.0,
    "ripple_amplitude": 0.0,
    "ripple_order": 6.0,
    "ripple_phase": 0.0,
    "current_time_constant": 0.0,
    "dead_time_steps": 0,
}


def ramp(duration: float, torque: float, hold: float = 0.0) -> np.ndarray:
    """Current (A) ramping linearly to ``torque`` (N.m) over ``duration`` s, then held."""
    t = np.arange(int(round((duration + hold) / H))) * H
    return np.minimum(t / duration, 1.0) * torque / K_T


def speed_loop(plant, parameters, speed: float, duration: float, outputs: tuple[str, ...]):
    """Hold the motor at ``speed`` rad/s with a PI loop; outputs sampled after every step."""
    plant.start_run(parameters)
    fmu = plant.fmu
    vr_in = plant.value_reference("current_cmd")
    vr_speed = plant.value_reference("motor_speed")
    vr_out = [plant.value_reference(n) for n in outputs]
    n = int(round(duration / H))
    values, current = np.empty((n, len(outputs))), np.empty(n)
    measured, integral = 0.0, 0.0
    for k in range(n):
        error = speed - measured
        integral += 20.0 * error
        current[k] = 0.5 * error + integral * H  # A; P 0.5 A/(rad/s), I 20 A/(rad/s)/s
        fmu.setReal([vr_in], [current[k]])
        fmu.doStep(k * H, H)
        measured = fmu.getReal([vr_speed])[0]
        values[k] = fmu.getReal(vr_out)
    return {"current": current, **{name: values[:, i] for i, name in enumerate(outputs)}}


def initial_outputs(plant, names: tuple[str, ...]) -> list[float]:
    """Outputs at the start, before the first doStep."""
    return plant.fmu.getReal([plant.value_reference(n) for n in names])


# ---------------------------------------------------------------- friction


def test_stribeck_breakaway_is_the_static_level(open_loop):
    """A slow torque ramp: the load stays put until the torque reaches F_C + F_x."""
    excess = 0.25  # N.m, F_S / F_C = 1.4
    current = ramp(2.0, 2.0 * F_C)  # 0.625 N.m/s, the coupling follows quasi-statically
    out = open_loop(
        current,
        H,
        {"stribeck_friction": excess, "stribeck_speed": 0.1},
        ("load_speed", "motor_torque", "friction_torque"),
    )
    moving = np.flatnonzero(out["load_speed"] != 0.0)
    start = moving[0]
    assert np.all(out["load_speed"][start:] > 0.0)  # it breaks away once and keeps sliding
    assert out["motor_torque"][start] == pytest.approx(F_C + excess, rel=0.01)
    # Standstill: friction balances the drive up to the static level, never beyond.
    assert out["friction_torque"][:start].max() == pytest.approx(F_C + excess, rel=0.01)
    assert np.all(out["friction_torque"][:start] <= F_C + excess + 1e-12)


def test_stribeck_sliding_follows_the_curve_and_high_speed_acceleration(open_loop):
    excess, v_s = 0.25, 1.0  # N.m, rad/s
    torque = 2.0 * F_C
    out = open_loop(
        np.full(int(1.0 / H), torque / K_T),
        H,
        {"stribeck_friction": excess, "stribeck_speed": v_s},
        ("load_speed", "friction_torque"),
    )
    w = out["load_speed"] / TRAVEL
    sliding = w > 0.0
    expected = F_C + excess * np.exp(-((w[sliding] / v_s) ** 2))
    np.testing.assert_allclose(out["friction_torque"][sliding], expected, rtol=1e-12)
    assert w[sliding].min() < 0.3 * v_s and w.max() > 10 * v_s  # the run crosses the drop
    window = out["t"] >= 0.2  # w >> v_s: only Coulomb friction is left
    slope = np.polyfit(out["t"][window], w[window], 1)[0]
    assert slope == pytest.approx((torque - F_C) / (J_M + J_L), rel=0.01)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_asymmetric_coulomb_friction_gives_two_accelerations(open_loop, sign):
    asymmetry = 0.15  # N.m: F_C + a forwards, F_C - a backwards
    torque = 2.0 * F_C
    out = open_loop(
        np.full(int(1.0 / H), sign * torque / K_T),
        H,
        {"coulomb_asymmetry": asymmetry},
        ("load_speed", "friction_torque"),
    )
    w = out["load_speed"] / TRAVEL
    window = out["t"] >= 0.2
    slope = np.polyfit(out["t"][window], w[window], 1)[0]
    level = F_C + sign * asymmetry
    assert slope == pytest.approx(sign * (torque - level) / (J_M + J_L), rel=0.01)
    np.testing.assert_allclose(out["friction_torque"][window], sign * level, rtol=1e-12)


def test_asymmetric_breakaway_levels(open_loop):
    """At rest the load holds a backward torque above F_C - a only up to F_C - a."""
    asymmetry = 0.15
    torque = F_C  # N.m, between F_C - a and F_C + a
    parameters = {"coulomb_asymmetry": asymmetry}
    forward = open_loop(ramp(0.5, torque, 0.5), H, parameters, ("load_speed",))
    assert np.all(forward["load_speed"] == 0.0)
    backward = open_loop(ramp(0.5, -torque, 0.5), H, parameters, ("load_speed",))
    assert backward["load_speed"][-1] < 0.0


def test_position_dependent_friction_follows_the_screw_angle(plant):
    amplitude, order, phase = 0.3, 3.0, 0.7
    out = speed_loop(
        plant,
        {
            "position_friction_amplitude": amplitude,
            "position_friction_order": order,
            "position_friction_phase": phase,
        },
        speed=10.0,  # rad/s at the motor: 1.06 mm/s at the carriage, a screw turn in 0.94 s
        duration=3.0,
        outputs=("load_angle", "load_speed", "friction_torque", "motor_speed"),
    )
    steady = slice(int(1.0 / H), None)
    screw_angle = out["load_angle"][steady] / GEAR
    assert np.all(out["load_speed"][steady] > 0.0)  # slides forwards throughout
    assert np.ptp(screw_angle) > 2 * 2 * math.pi / order  # at least two friction cycles
    expected = F_C * (1 + amplitude * np.cos(order * screw_angle + phase))
    np.testing.assert_allclose(out["friction_torque"][steady], expected, rtol=1e-12)
    # The speed loop supplies the friction: its current follows the same curve.
    torque = K_T * out["current"][steady]
    assert np.corrcoef(torque, expected)[0, 1] > 0.98
    assert np.ptp(torque) == pytest.approx(2 * amplitude * F_C, rel=0.1)


def test_lugre_pre_sliding_below_coulomb(open_loop):
    """A torque below F_C deflects the bristles: a small, bounded displacement, no sliding.

    Quasi-statically sigma_0 z = T and dq_L = dz / (1 - sigma_0 z / F_C), so the load moves
    -(F_C / sigma_0) ln(1 - T / F_C): about T / sigma_0 for T well below F_C.
    """
    sigma_0 = 200.0  # N.m/rad
    sigma_1 = 2 * math.sqrt(sigma_0 * J_L)  # N.m.s/rad, critical bristle damping
    torque = 0.4 * F_C
    out = open_loop(
        ramp(0.5, torque, 1.0),
        H,
        {"lugre_stiffness": sigma_0, "lugre_damping": sigma_1, "backlash": 0.0},
        ("load_angle", "load_speed", "friction_torque"),
    )
    displacement = out["load_angle"][-1]
    expected = -(F_C / sigma_0) * math.log(1 - torque / F_C)
    assert displacement == pytest.approx(expected, rel=0.02)
    assert torque / sigma_0 < displacement < 1.3 * torque / sigma_0
    hold = out["t"] >= 1.0
    assert np.ptp(out["load_angle"][hold]) < 1e-3 * displacement  # no creep, no sliding
    assert np.abs(out["load_speed"][hold]).max() < 1e-3 * TRAVEL
    assert out["friction_torque"][-1] == pytest.approx(torque, rel=1e-3)


def test_lugre_friction_at_speed_is_coulomb_plus_viscous(open_loop):
    sigma_0, viscous = 200.0, 0.002  # N.m/rad, N.m.s/rad
    torque = 1.5 * F_C
    out = open_loop(
        np.full(int(0.3 / H), torque / K_T),
        H,
        {"lugre_stiffness": sigma_0, "lugre_damping": 0.5, "viscous_friction": viscous},
        ("load_speed", "friction_torque"),
    )
    w = out["load_speed"] / TRAVEL
    fast = out["t"] >= 0.2
    assert w[fast].min() > 50.0  # rad/s
    np.testing.assert_allclose(out["friction_torque"][fast], F_C + viscous * w[fast], rtol=1e-4)


# ---------------------------------------------------------------- transmission and measurement


def test_lead_error_maps_the_load_angle_to_the_carriage(open_loop, plant):
    start = 0.01  # m
    lead, errors, phases = 0.002, (3e-6, 1.5e-6, 0.8e-6), (0.4, -1.2, 2.5)
    parameters = {"load_position_start": start, "pitch_error_linear": lead}
    for k, (e, phi) in enumerate(zip(errors, phases, strict=True), start=1):
        parameters |= {f"pitch_error_amplitude_{k}": e, f"pitch_error_phase_{k}": phi}
    plant.start_run(parameters)
    assert initial_outputs(plant, ("load_position_true", "load_position")) == [start, start]
    out = open_loop(
        np.full(int(0.5 / H), 2.0 * F_C / K_T),
        H,
        parameters,
        ("load_angle", "load_position_true", "load_position", "load_speed"),
    )

    def harmonics(load_angle):
        return sum(
            e * np.sin(k * load_angle / GEAR + phi)
            for k, (e, phi) in enumerate(zip(errors, phases, strict=True), start=1)
        )

    angle_0 = start / TRAVEL
    angle = out["load_angle"]
    expected = (
        start + TRAVEL * (angle - angle_0) * (1 + lead) + harmonics(angle) - harmonics(angle_0)
    )
    assert np.ptp(angle) / GEAR > 4 * math.pi  # over two screw turns
    np.testing.assert_allclose(out["load_position_true"], expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out["load_position"], out["load_position_true"])
    # load_speed is the time derivative of load_position_true (away from the breakaway kink).
    smooth = slice(int(0.1 / H), -1)
    derivative = np.gradient(out["load_position_true"], H)
    np.testing.assert_allclose(out["load_speed"][smooth], derivative[smooth], rtol=1e-5)


def test_scale_reading_is_quantised(open_loop):
    q = 1e-6  # m
    noise = (0.3e-6, 75.0, 0.2)  # m, Hz, rad
    parameters = {
        "position_resolution": q,
        "noise_amplitude_1": noise[0],
        "noise_frequency_1": noise[1],
        "noise_phase_1": noise[2],
    }
    out = open_loop(
        np.full(int(0.3 / H), 1.5 * F_C / K_T),
        H,
        parameters,
        ("load_position", "load_position_true"),
    )
    steps = out["load_position"] / q
    np.testing.assert_allclose(steps, np.round(steps), rtol=0, atol=1e-6)
    unquantised = out["load_position_true"] + noise[0] * np.sin(
        2 * np.pi * noise[1] * out["t"] + noise[2]
    )
    error = out["load_position"] - unquantised
    assert np.abs(error).max() <= q / 2 * (1 + 1e-9)
    assert np.ptp(steps) > 100  # many levels crossed
    assert np.std(error) == pytest.approx(q / math.sqrt(12), rel=0.1)  # uniform quantiser


def test_thermal_drift_scales_the_travel(open_loop):
    rate = 1e-4  # 1/s
    out = open_loop(
        np.full(int(0.5 / H), 2.0 * F_C / K_T),
        H,
        {"thermal_expansion_rate": rate},
        ("load_angle", "load_position_true", "load_speed"),
    )
    moving = out["load_angle"] > 0.0
    scale = out["load_position_true"][moving] / (TRAVEL * out["load_angle"][moving])
    np.testing.assert_allclose(scale, 1 + rate * out["t"][moving], rtol=1e-12)
    smooth = slice(int(0.1 / H), -1)  # away from the breakaway kink
    derivative = np.gradient(out["load_position_true"], H)
    np.testing.assert_allclose(out["load_speed"][smooth], derivative[smooth], rtol=1e-6)


# ---------------------------------------------------------------- motor and drive


def test_torque_ripple_is_a_motor_angle_harmonic(open_loop):
    amplitude, order, phase = 0.05, 6.0, 0.4
    current = np.full(int(0.3 / H), 2.0 * F_C / K_T)
    out = open_loop(
        current,
        H,
        {"ripple_amplitude": amplitude, "ripple_order": order, "ripple_phase": phase},
        ("motor_torque", "motor_angle", "current_applied"),
    )
    np.testing.assert_array_equal(out["current_applied"], current)
    ripple = out["motor_torque"] - K_T * current
    expected = amplitude * np.sin(order * out["motor_angle"] + phase)
    np.testing.assert_allclose(ripple, expected, rtol=0, atol=1e-15)
    assert np.ptp(out["motor_angle"]) > 2 * math.pi  # over a full motor turn


def test_torque_ripple_does_work_as_a_potential(open_loop):
    """Without losses, K_t i dq_M plus the ripple's work equals the stored energy.

    The ripple A sin(k q + phi) has the potential (A/k) cos(k q + phi).
    """
    amplitude, order, phase, current = 0.08, 6.0, 0.4, 0.5  # N.m, 1, rad, A
    out = open_loop(
        np.full(int(0.2 / H), current),
        H,
        {**LOSSLESS, "ripple_amplitude": amplitude, "ripple_order": order, "ripple_phase": phase},
        ("motor_angle", "motor_speed", "load_speed", "shaft_torque"),
    )
    angle = out["motor_angle"]
    work = K_T * current * angle - amplitude / order * (
        np.cos(order * angle + phase) - math.cos(phase)
    )
    stored = (
        0.5 * J_M * out["motor_speed"] ** 2
        + 0.5 * J_L * (out["load_speed"] / TRAVEL) ** 2
        + 0.5 * out["shaft_torque"] ** 2 / STIFFNESS
    )
    assert np.abs(stored - work).max() < 1e-6 * work.max()
    assert amplitude / order * 2 > 1e-3 * work.max()  # the ripple's share is far above the bound


def test_current_lag_is_first_order(open_loop):
    tau = 1e-3  # s, 16 speed-loop steps
    out = open_loop(
        np.ones(int(0.01 / H)),
        H,
        {"current_time_constant": tau},
        ("current_applied", "motor_torque"),
    )
    at_tau = int(round(tau / H)) - 1  # sample at t = tau
    assert out["t"][at_tau] == pytest.approx(tau)
    assert out["current_applied"][at_tau] == pytest.approx(1 - math.exp(-1), rel=0.01)
    np.testing.assert_allclose(out["current_applied"], 1 - np.exp(-out["t"] / tau), atol=1e-8)
    np.testing.assert_allclose(out["motor_torque"], K_T * out["current_applied"], rtol=1e-15)


def test_dead_time_delays_the_torque_by_whole_steps(open_loop):
    delay, first = 5, 10  # steps
    current = np.zeros(200)
    current[first:] = 2.0 * F_C / K_T
    parameters = {"backlash": 0.0}
    outputs = ("motor_speed", "current_applied", "motor_torque")
    prompt = open_loop(current, H, parameters, outputs)
    late = open_loop(current, H, {**parameters, "dead_time_steps": delay}, outputs)
    assert np.flatnonzero(prompt["motor_speed"])[0] == first
    assert np.flatnonzero(late["motor_speed"])[0] == first + delay
    np.testing.assert_array_equal(late["current_applied"][delay:], current[:-delay])
    np.testing.assert_array_equal(late["current_applied"][:delay], 0.0)
    np.testing.assert_allclose(late["motor_speed"][delay:], prompt["motor_speed"][:-delay])


def test_dead_time_then_lag(open_loop):
    delay, tau = 3, 0.5e-3  # steps, s
    current = np.ones(100)
    out = open_loop(
        current,
        H,
        {"dead_time_steps": delay, "current_time_constant": tau},
        ("current_applied",),
    )
    t_acting = out["t"] - delay * H  # time since the command reached the current loop
    expected = np.where(t_acting > 0, 1 - np.exp(-np.maximum(t_acting, 0) / tau), 0.0)
    np.testing.assert_allclose(out["current_applied"], expected, atol=1e-8)


# ---------------------------------------------------------------- bad values and defaults


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        ({"coulomb_asymmetry": 0.7}, r"coulomb_asymmetry = 0.7 is invalid"),
        ({"coulomb_asymmetry": -0.3, "coulomb_friction": 0.2}, r"coulomb_asymmetry = -0.3"),
        ({"position_resolution": -1e-6}, r"position_resolution = -1e-06 is invalid"),
        ({"stribeck_friction": math.nan}, r"stribeck_friction = nan is invalid"),
        ({"stribeck_speed": 0.0}, r"stribeck_speed = 0 is invalid"),
        ({"position_friction_amplitude": 1.0}, r"position_friction_amplitude = 1 is invalid"),
        ({"pitch_error_amplitude_3": 2e-3}, r"pitch_error_amplitude_3 = 0.002 is invalid"),
        ({"thermal_expansion_rate": math.inf}, r"thermal_expansion_rate = inf is invalid"),
        ({"current_time_constant": -1e-3}, r"current_time_constant = -0.001 is invalid"),
        ({"ripple_order": 0.0}, r"ripple_order = 0 is invalid"),
        ({"dead_time_steps": 65}, r"dead_time_steps = 65 is out of range"),
        ({"lugre_stiffness": 100.0, "coulomb_friction": 0.0}, r"lugre_stiffness = 100 needs"),
    ],
)
def test_bad_effect_parameters_are_refused(plant, parameters, message):
    with pytest.raises(PlantError, match=message):
        plant.start_run(parameters)
    plant.start_run({})  # the instance recovers through fmi2Reset


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        ({"current_time_constant": 1e-6}, "too long"),  # 1/tau far beyond the RK4 limit
        ({"lugre_stiffness": 1e7}, "too long"),  # sqrt(sigma_0 / J_L) beyond the RK4 limit
    ],
)
def test_stiff_effects_ask_for_more_substeps(plant, parameters, message):
    plant.start_run(parameters)
    plant.messages.clear()
    with pytest.raises(FMICallException):
        plant.fmu.doStep(0.0, H)
    assert any(message in m for m in plant.messages), plant.messages


def test_lugre_bristle_rate_is_checked_at_speed(plant):
    """The bristle relaxation rate sigma_0 |w_L| / F_C grows with speed; doStep says so."""
    plant.start_run({"lugre_stiffness": 1000.0, "lugre_damping": 1.0})
    fmu = plant.fmu
    fmu.setReal([plant.value_reference("current_cmd")], [4.0 * F_C / K_T])
    plant.messages.clear()
    with pytest.raises(FMICallException):
        for k in range(int(1.0 / H)):
            fmu.doStep(k * H, H)
    assert any("LuGre bristles" in m for m in plant.messages), plant.messages


def test_contract_defaults_are_the_fmu_start_values(plant):
    starts = plant.start_values()
    assert {name: starts[name] for name in EFFECT_DEFAULTS} == EFFECT_DEFAULTS


def test_explicit_defaults_change_nothing_in_closed_loop(plant):
    scenario = load_scenario(SCENARIO)
    default = run_scenario(plant, scenario)
    explicit = run_scenario(plant, scenario, plant_overrides=EFFECT_DEFAULTS)
    assert np.array_equal(default.to_numpy(), explicit.to_numpy())


@pytest.mark.parametrize("steps", [[H], [H, 0.3 * H, 1.7 * H, 0.55 * H]], ids=["H", "variable"])
def test_dead_time_is_in_seconds_at_any_step(plant, steps):
    """Lossless axis: total momentum J_M w_M + J_L w_L = K_t * integral of the delayed current,
    which RK4 keeps exactly; the current acts dead_time_steps * sample_period late whatever the
    communication steps, also when a delayed change falls inside a step."""
    delay, switch_at = 7, 40 * H  # sample periods, s
    pattern = np.resize(steps, 400)
    times = np.concatenate([[0.0], np.cumsum(pattern)])
    switch = times[np.searchsorted(times, switch_at)]
    plant.start_run({**LOSSLESS, "dead_time_steps": delay})
    vr_in = plant.value_reference("current_cmd")
    vr_out = [plant.value_reference(n) for n in ("motor_speed", "load_speed", "current_applied")]
    values = []
    for t, t_next in zip(times[:-1], times[1:], strict=True):
        plant.fmu.setReal([vr_in], [2.0 if t < switch else -1.0])
        plant.fmu.doStep(t, t_next - t)
        values.append(plant.fmu.getReal(vr_out))
    motor_speed, load_speed, current = np.array(values).T
    t = times[1:]
    dead_time = delay * H
    impulse = K_T * (
        2.0 * np.clip(np.minimum(t, switch + dead_time) - dead_time, 0.0, None)
        - 1.0 * np.clip(t - switch - dead_time, 0.0, None)
    )  # N.m.s
    momentum = J_M * motor_speed + J_L * load_speed / TRAVEL
    np.testing.assert_allclose(momentum, impulse, rtol=1e-9, atol=1e-12)
    # the command acting at the end of each step; a change exactly at the end acts in the next
    late = dead_time + 1e-12
    expected = np.where(t <= late, 0.0, np.where(t <= switch + late, 2.0, -1.0))
    np.testing.assert_array_equal(current, expected)
