"""drive2mass against physics: transfer functions (3)-(4), energy, backlash, friction, noise.

Every expectation comes from the paper's equations or from mechanics, never from an earlier run.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares

from twin_cosim.plant_model import plant_model

J_M, J_L = 2.9e-4, 4.2e-4  # kg.m2, Table 1
F_01, D_1 = 70.0, 0.15  # Hz, 1
K_T, F_C = 0.74, 0.625  # N.m/A, N.m
BACKLASH = 12.2e-6  # m
TRAVEL = plant_model("drive2mass").drive_facts()["travel_per_rad"]  # m per motor rad
W_01 = 2 * math.pi * F_01
STIFFNESS = J_L * W_01**2  # N.m/rad, eq. (1)
W_02 = W_01 * math.sqrt(1 + J_L / J_M)
D_2 = D_1 * math.sqrt(1 + J_L / J_M)  # eq. (2)
LINEAR = {"backlash": 0.0, "coulomb_friction": 0.0, "viscous_friction": 0.0}


def h_motor(w: np.ndarray, j_m=J_M, w1=W_01, d1=D_1, w2=W_02, d2=D_2) -> np.ndarray:
    """Eq. (3): motor speed / motor torque."""
    s = 1j * w
    return (s**2 + 2 * d1 * w1 * s + w1**2) / (j_m * s * (s**2 + 2 * d2 * w2 * s + w2**2))


def h_load(w: np.ndarray, w1=W_01, d1=D_1) -> np.ndarray:
    """Eq. (4): load speed / motor speed."""
    s = 1j * w
    return (2 * d1 * w1 * s + w1**2) / (s**2 + 2 * d1 * w1 * s + w1**2)


def sine_response(
    open_loop, frequency: float, h: float = 10e-6, settle: float = 0.12, cycles: int = 12
):
    """Motor speed per motor torque (rad/s per N.m) and load over motor speed at one frequency.

    The input is zero-order held over each step; its phasor is corrected by the ZOH factor.
    """
    n_fit = int(round(cycles / frequency / h))
    n = int(settle / h) + n_fit
    w = 2 * math.pi * frequency
    t_start = np.arange(n) * h
    amplitude = 0.5  # A
    out = open_loop(
        amplitude * np.sin(w * t_start), h, {**LINEAR, "substeps": 1}, ("motor_speed", "load_speed")
    )
    t = out["t"][-n_fit:]
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    phasors = []
    for name in ("motor_speed", "load_speed"):
        (a, b, _), *_ = np.linalg.lstsq(basis, out[name][-n_fit:], rcond=None)
        phasors.append(a + 1j * b)  # a sin + b cos = Im((a + j b) e^{jwt}) with phasor a + j b
    zoh = np.exp(-1j * w * h / 2) * np.sinc(w * h / 2 / np.pi)
    torque = K_T * amplitude * zoh
    motor, load = phasors[0] / torque, phasors[1] / TRAVEL / torque
    return motor, load / motor


@pytest.fixture(scope="module")
def frequency_response(fmu_path):
    from twin_cosim.plant import Plant

    frequencies = np.geomspace(30.0, 250.0, 28)
    with Plant(fmu_path) as plant:

        def open_loop(current, h, parameters, outputs):
            plant.start_run(parameters)
            vr_in = [plant.value_reference("current_cmd")]
            vr_out = [plant.value_reference(n) for n in outputs]
            values = np.empty((len(current), len(outputs)))
            for k, u in enumerate(current):
                plant.fmu.setReal(vr_in, [float(u)])
                plant.fmu.doStep(k * h, h)
                values[k] = plant.fmu.getReal(vr_out)
            return {
                **{n: values[:, i] for i, n in enumerate(outputs)},
                "t": (np.arange(len(current)) + 1) * h,
            }

        data = [sine_response(open_loop, f) for f in frequencies]
    return frequencies, np.array([d[0] for d in data]), np.array([d[1] for d in data])


def test_motor_frequency_response_matches_eq3(frequency_response):
    frequencies, motor, _ = frequency_response
    w = 2 * np.pi * frequencies

    def residual(p):
        model = h_motor(w, p[0] * 1e-4, p[1], p[2], p[3], p[4])
        rel = (model - motor) / np.abs(motor)
        return np.concatenate([rel.real, rel.imag])

    fit = least_squares(residual, [2.5, 400.0, 0.1, 600.0, 0.2])
    antiresonance_hz, resonance_hz = fit.x[1] / (2 * np.pi), fit.x[3] / (2 * np.pi)
    assert antiresonance_hz == pytest.approx(F_01, rel=0.01)
    assert resonance_hz == pytest.approx(W_02 / (2 * np.pi), rel=0.01)
    assert fit.x[2] == pytest.approx(D_1, rel=0.05)
    assert fit.x[4] == pytest.approx(D_2, rel=0.05)
    for f in (30.0, 70.0, 110.0, 250.0):
        i = int(np.argmin(np.abs(frequencies - f)))
        assert abs(motor[i]) == pytest.approx(abs(h_motor(w[i])), rel=0.02)


def test_load_over_motor_response_matches_eq4(frequency_response):
    frequencies, _, ratio = frequency_response
    w = 2 * np.pi * frequencies
    expected = h_load(w)
    np.testing.assert_allclose(np.abs(ratio), np.abs(expected), rtol=0.02)
    peak = int(np.argmax(np.abs(ratio)))
    assert frequencies[peak] == pytest.approx(
        frequencies[int(np.argmax(np.abs(expected)))], rel=0.01
    )


def test_energy_is_conserved_without_losses(open_loop):
    h = 62.5e-6
    n = int(1.02 / h)
    kick = np.zeros(n)
    kick[: int(0.02 / h)] = 1.0  # 1 A for 20 ms, then free oscillation
    out = open_loop(
        kick, h, {**LINEAR, "damping_ratio": 0.0}, ("motor_speed", "load_speed", "shaft_torque")
    )
    free = slice(int(0.02 / h), None)
    w_load = out["load_speed"][free] / TRAVEL
    energy = (
        0.5 * J_M * out["motor_speed"][free] ** 2
        + 0.5 * J_L * w_load**2
        + 0.5 * out["shaft_torque"][free] ** 2 / STIFFNESS
    )
    spring = 0.5 * out["shaft_torque"][free] ** 2 / STIFFNESS
    assert spring.max() > 1e-3 * energy[0]  # it really oscillates
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-6


@pytest.mark.parametrize("coulomb", [0.0, F_C])
def test_lost_motion_equals_backlash_plus_twist(plant, coulomb):
    h = 62.5e-6
    gain = 0.5  # A/(rad/s), stiff enough to hold 0.5 rad/s within a few percent
    viscous = (
        0.02 if coulomb == 0 else 0.0
    )  # N.m.s/rad: without Coulomb friction the load must still stop
    parameters = {"coulomb_friction": coulomb, "viscous_friction": viscous}
    plant.start_run(parameters)
    fmu = plant.fmu
    vr_in = [plant.value_reference("current_cmd")]
    vr_out = [
        plant.value_reference(n) for n in ("motor_speed", "motor_angle", "load_position_true")
    ]
    n = int(3.0 / h)
    speed, angle, load = fmu.getReal(vr_out)
    integral = 0.0
    motor_travel, load_travel = np.empty(n), np.empty(n)
    for k in range(n):
        reference = 0.5 if k * h < 1.5 else -0.5  # rad/s at the motor, 0.53 mm/s at the carriage
        integral += 0.05 * (reference - speed)
        fmu.setReal(vr_in, [gain * (reference - speed) + integral])
        fmu.doStep(k * h, h)
        speed, angle, load = fmu.getReal(vr_out)
        motor_travel[k], load_travel[k] = angle * TRAVEL, load
    forward = slice(int(1.0 / h), int(1.5 / h))  # steady forward motion
    backward = slice(int(2.5 / h), n)  # steady backward motion
    offset_forward = np.mean(motor_travel[forward] - load_travel[forward])
    offset_backward = np.mean(motor_travel[backward] - load_travel[backward])
    lost_motion = offset_forward - offset_backward
    twist = (coulomb + viscous * 0.5) / STIFFNESS  # rad, friction torque at 0.5 rad/s over K
    expected = BACKLASH + 2 * twist * TRAVEL
    assert lost_motion == pytest.approx(expected, rel=0.02)
    # After the reversal the motor crosses the whole gap (relative to the load) before the load
    # starts back.
    load_turn = int(np.argmax(load_travel))
    starts_back = load_turn + int(
        np.argmax(load_travel[load_turn:] < load_travel[load_turn] - 0.01 * BACKLASH)
    )
    assert offset_forward - (motor_travel[starts_back] - load_travel[starts_back]) >= BACKLASH


def test_torque_below_coulomb_holds_the_load(open_loop):
    """A torque below F_C, ramped in over 0.2 s and then held for 1 s, never moves the load.

    The ramp matters: a torque step makes the motor cross the gap freely and hit the load; the
    impact torque then exceeds F_C (energy balance: peak twist (T + sqrt(T^2 + 2 K T b)) / K) and
    the load does move, as a real axis would.
    """
    h = 62.5e-6
    torque = 0.8 * F_C
    current = np.minimum(np.arange(int(1.2 / h)) * h / 0.2, 1.0) * torque / K_T
    out = open_loop(current, h, {}, ("load_position_true", "motor_angle"))
    assert np.all(out["load_position_true"] == 0.0)
    half_gap = BACKLASH / 2 / TRAVEL
    assert out["motor_angle"][-1] == pytest.approx(half_gap + torque / STIFFNESS, rel=1e-3)


def test_torque_above_coulomb_accelerates_the_axis(open_loop):
    h = 62.5e-6
    torque = 2.0 * F_C
    out = open_loop(np.full(int(1.0 / h), torque / K_T), h, {}, ("load_speed",))
    speed = out["load_speed"] / TRAVEL
    t = out["t"]
    window = t >= 0.2
    slope = np.polyfit(t[window], speed[window], 1)[0]
    assert slope == pytest.approx((torque - F_C) / (J_M + J_L), rel=0.01)


def test_no_chattering_at_standstill_with_friction(open_loop):
    h = 62.5e-6
    # A torque that oscillates around zero below the Coulomb level: the load never moves.
    t = np.arange(int(0.5 / h)) * h
    out = open_loop(
        0.9 * F_C / K_T * np.sin(2 * np.pi * 5 * t), h, {}, ("load_speed", "friction_torque")
    )
    assert np.all(out["load_speed"] == 0.0)
    assert np.all(np.abs(out["friction_torque"]) <= F_C + 1e-12)


def test_noise_spectrum_shows_exactly_the_set_harmonics(open_loop):
    h = 62.5e-6
    harmonics = {1: (0.4e-6, 50.0, 0.3), 2: (0.15e-6, 120.0, -1.0), 3: (0.05e-6, 400.0, 2.0)}
    parameters = {}
    for k, (amplitude, frequency, phase) in harmonics.items():
        parameters |= {
            f"noise_amplitude_{k}": amplitude,
            f"noise_frequency_{k}": frequency,
            f"noise_phase_{k}": phase,
        }
    n = int(1.0 / h)  # 1 s: every set frequency falls on an FFT bin
    out = open_loop(np.zeros(n), h, parameters, ("load_position", "load_position_true"))
    assert np.all(out["load_position_true"] == 0.0)
    spectrum = np.abs(np.fft.rfft(out["load_position"])) * 2 / n
    bins = np.fft.rfftfreq(n, h)
    expected = np.zeros_like(spectrum)
    for amplitude, frequency, _ in harmonics.values():
        expected[int(round(frequency))] = amplitude
    np.testing.assert_allclose(spectrum, expected, atol=1e-3 * 0.05e-6)
    assert bins[int(round(harmonics[3][1]))] == 400.0
