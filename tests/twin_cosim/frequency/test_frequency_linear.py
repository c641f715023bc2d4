"""The linear two-mass plant and the linearised loops against eqs. (1)-(4) and python-control."""

from __future__ import annotations

import dataclasses
import math

import control
import numpy as np
import pytest
from scipy.signal import cont2discrete

from twin_cosim.controller import ControllerSettings
from twin_cosim.controller_set import TABLE3
from twin_cosim.current_filters import Notch
from twin_cosim.frequency.linear import (
    LinearLoops,
    TwoMass,
    closed,
    hold_discretised,
    speed_loop_of_plant,
)
from twin_cosim.frequency.margins import dense_grid, margins_of_data, margins_of_system

J_M, J_L, F_1, D_1 = 2.9e-4, 4.2e-4, 70.0, 0.15  # Table 1
W_01 = 2 * math.pi * F_1
W_02 = W_01 * math.sqrt(1 + J_L / J_M)  # eq. (1)
D_2 = D_1 * math.sqrt(1 + J_L / J_M)  # eq. (2)
PLANT = TwoMass.of_plant("drive2mass")
F = np.geomspace(1.0, 2000.0, 300)


def eq3(f):
    s = 2j * np.pi * f
    return (s**2 + 2 * D_1 * W_01 * s + W_01**2) / (J_M * s * (s**2 + 2 * D_2 * W_02 * s + W_02**2))


def eq4(f):
    s = 2j * np.pi * f
    return (2 * D_1 * W_01 * s + W_01**2) / (s**2 + 2 * D_1 * W_01 * s + W_01**2)


def test_the_card_gives_table1_two_mass():
    assert PLANT.antiresonance_hz == pytest.approx(F_1)
    assert PLANT.damping_ratio == pytest.approx(D_1)
    assert PLANT.resonance_hz == pytest.approx(W_02 / (2 * math.pi))
    paper = TwoMass.from_paper(J_M, J_L, F_1, D_1, torque_constant=0.74)
    assert paper.stiffness == pytest.approx(PLANT.stiffness)
    assert paper.damping == pytest.approx(PLANT.damping)


def test_transfer_functions_are_eqs_3_and_4():
    np.testing.assert_allclose(PLANT.speed_per_torque(F), eq3(F), rtol=1e-12)
    np.testing.assert_allclose(PLANT.load_per_motor(F), eq4(F), rtol=1e-12)


def test_state_space_is_the_transfer_function_with_lag():
    plant = PLANT.with_values(current_lag=2e-4, viscous_friction=0.01)
    a, b, c = plant.state_space(with_position=True)
    s = 2j * np.pi * F
    response = np.array([c @ np.linalg.solve(z * np.eye(len(a)) - a, b) for z in s])[:, :, 0]
    expected = plant.speed_per_torque(F) * plant.torque_per_current(F)
    np.testing.assert_allclose(response[:, 0], expected, rtol=1e-9)
    np.testing.assert_allclose(  # x = travel q_L, q_L = w_L / s
        response[:, 1], expected * plant.load_per_motor(F) * plant.travel_per_rad / s, rtol=1e-9
    )


def test_hold_discretisation_and_dead_time_agree_with_scipy():
    plant = PLANT.with_values(dead_time=2 * 62.5e-6)
    a, b, c = plant.state_space(with_position=False)
    ad, bd, cd, dd, _ = cont2discrete((a, b, c, np.zeros((1, 1))), 62.5e-6, method="zoh")
    z = np.exp(2j * np.pi * F * 62.5e-6)
    expected = np.array([(cd @ np.linalg.solve(q * np.eye(len(ad)) - ad, bd))[0, 0] for q in z])
    held = hold_discretised(plant, 62.5e-6, with_position=False)
    np.testing.assert_allclose(held.siso(F), expected * z**-2, rtol=1e-8)
    with pytest.raises(ValueError, match="whole number of speed-loop periods"):
        hold_discretised(PLANT.with_values(dead_time=1e-4), 62.5e-6, with_position=False)


@pytest.mark.parametrize("name", sorted(TABLE3))
@pytest.mark.parametrize("loop", ["speed", "position"])
def test_margins_of_the_loop_data_agree_with_python_control(name, loop):
    loops = LinearLoops(PLANT, TABLE3[name], ControllerSettings(filters=(Notch(110, 50, -15),)))
    system = loops.open_loop(loop)
    grid = dense_grid(0.5, 0.5 / system.dt)
    ours = margins_of_data(grid, system.siso(grid))
    theirs = margins_of_system(system)
    assert ours.gain_margin_db == pytest.approx(theirs.gain_margin_db, abs=0.01)
    assert ours.phase_margin_deg == pytest.approx(theirs.phase_margin_deg, abs=0.01)
    assert ours.crossover_hz == pytest.approx(theirs.crossover_hz, rel=1e-3)
    assert ours.bandwidth_hz == pytest.approx(theirs.bandwidth_hz, rel=1e-3)


def test_python_control_margins_of_a_continuous_loop_are_read_alike():
    """A plain second-order loop k / (s (s + 1)) sampled fast: phase margin known in closed form."""
    k = 4.0
    grid = np.geomspace(1e-3, 10.0, 4000)
    s = 2j * np.pi * grid
    loop = k / (s * (s + 1))
    _, pm, _, _, wc, _ = control.stability_margins(control.tf([k], [1, 1, 0]))
    ours = margins_of_data(grid, loop)
    assert ours.phase_margin_deg == pytest.approx(pm, abs=0.01)
    assert ours.crossover_hz == pytest.approx(wc / (2 * math.pi), rel=1e-4)
    assert ours.gain_margin_db is None


def test_speed_loop_from_the_plant_is_the_linearised_speed_loop():
    """Continuous plant times the hold's exp(-j w T/2) sinc: exact but for aliasing (0.4 %
    at 500 Hz, growing as f^2)."""
    settings = ControllerSettings(filters=(Notch(110, 50, -15),))
    loops = LinearLoops(PLANT, TABLE3["ft"], settings)
    f = np.geomspace(1.0, 500.0, 200)
    from_plant = speed_loop_of_plant(TABLE3["ft"], settings, f, loops.plant_response(f))
    np.testing.assert_allclose(from_plant, loops.speed_open().siso(f), rtol=5e-3)


def test_notch_on_the_resonance_lowers_the_speed_loop_peak():
    f = np.array([PLANT.resonance_hz])
    plain = LinearLoops(PLANT, TABLE3["ft"], ControllerSettings())
    notched = LinearLoops(
        PLANT, TABLE3["ft"], ControllerSettings(filters=(Notch(f[0], 60.0, -20.0),))
    )
    ratio = abs(notched.speed_open().siso(f)[0] / plain.speed_open().siso(f)[0])
    assert ratio == pytest.approx(0.1, rel=1e-6)


def test_static_stiffness_of_a_p_only_cascade_is_kp_pos_kp_vel_kt_over_travel_squared():
    """Without the speed loop's integral, a torque M at the load holds the axis off by
    x = M travel / (K_t Kp_vel Kp_pos): the force M / travel over x."""
    tuned = dataclasses.replace(TABLE3["ft"], Ki_vel=0.0)
    settings = ControllerSettings()
    stiffness = LinearLoops(PLANT, tuned, settings).dynamic_stiffness(np.array([1e-3]))[0]
    expected = tuned.Kp_pos * tuned.Kp_vel * 0.74 / settings.travel_per_rad**2 * 1e-6
    assert stiffness.real == pytest.approx(expected, rel=1e-6)
    assert abs(stiffness.imag) < 1e-3 * expected


@pytest.mark.parametrize("name", ["ft", "ga"])
def test_low_frequency_stiffness_of_the_pi_cascade_grows_as_one_over_frequency(name):
    """With the integral Ki = Ki_vel / T (A/rad), the position error of a torque M is
    travel (M / (K_t Ki) + M / K) s / Kp_pos at low frequency: the coupling K twists under M
    and the integral must also wind that twist back."""
    tuned, settings = TABLE3[name], ControllerSettings()
    f = np.array([0.01, 0.02])
    stiffness = np.abs(LinearLoops(PLANT, tuned, settings).dynamic_stiffness(f))
    integral = tuned.Ki_vel / settings.speed_period
    compliance = (1 / (0.74 * integral) + 1 / PLANT.stiffness) / tuned.Kp_pos
    expected = 1 / (settings.travel_per_rad**2 * 2 * np.pi * f * compliance) * 1e-6
    np.testing.assert_allclose(stiffness, expected, rtol=2e-3)


def test_sensitivity_and_closed_loop_add_up_to_one():
    loops = LinearLoops(PLANT, TABLE3["ft"], ControllerSettings())
    for loop in ("speed", "position"):
        s = loops.response(loop, "sensitivity", F[F < 1000])
        t = loops.response(loop, "closed", F[F < 1000])
        np.testing.assert_allclose(s + t, 1.0, atol=1e-9)


def test_the_cascade_with_a_disturbance_input_keeps_the_reference_path():
    loops = LinearLoops(PLANT, TABLE3["ft"], ControllerSettings())
    f = F[F < 1000]
    with_disturbance = closed(loops.position_open(with_disturbance=True)).response(f)[:, 0, 0]
    np.testing.assert_allclose(with_disturbance, closed(loops.position_open()).siso(f), rtol=1e-9)
