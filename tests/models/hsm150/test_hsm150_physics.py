"""The hsm150 rotor against mechanics: a torque step's exponential approach, the energy balance,
asymmetric friction and torque constant, the dead time, the encoder, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest

from fmu_build.build import build_fmu
from twin_cosim.plant import Plant, PlantError

J, B, KT = 1.2e-4, 7.03e-5, 0.0458  # kg.m2, N.m.s/rad, N.m/A: the catalogue
GRID = 2 * np.pi / 10000  # rad, the encoder


@pytest.fixture(scope="module")
def rotor():
    with Plant(build_fmu("hsm150")) as plant:
        yield plant


def step(plant: Plant, commands, parameters, h=1e-3, outputs=("rotor_speed",), torque=0.0):
    """Outputs after each step with current command ``commands[k]`` (A) set before step k."""
    plant.start_run(parameters)
    vr_in = [plant.value_reference("current_cmd"), plant.value_reference("disturbance_torque")]
    vr_out = [plant.value_reference(n) for n in outputs]
    values = []
    for k, u in enumerate(commands):
        plant.fmu.setReal(vr_in, [float(u), torque])
        plant.fmu.doStep(k * h, h)
        values.append(plant.fmu.getReal(vr_out))
    return {name: np.array(values)[:, i] for i, name in enumerate(outputs)}


def test_a_torque_step_approaches_its_terminal_speed_with_time_constant_j_over_b(rotor):
    """w(t) = (tau - F_c) / B (1 - exp(-t B / J)) from rest; the rotor, held by static friction
    at t = 0, breaks away at the end of the first substep (0.1 ms)."""
    tau, coulomb, h = 0.06, 0.02, 1e-3
    out = step(rotor, np.full(8000, tau / KT), {"coulomb_friction": coulomb})
    t = np.arange(1, 8001) * h
    substep = h / 10
    analytic = (tau - coulomb) / B * (1 - np.exp(-(t - substep) * B / J))
    np.testing.assert_allclose(out["rotor_speed"], analytic, rtol=1e-8)
    # the catalogue without Coulomb friction runs to 0.06 / B = 853 rad/s, 63 % of it at J/B
    out = step(rotor, np.full(8000, tau / KT), {})
    np.testing.assert_allclose(out["rotor_speed"], tau / B * (1 - np.exp(-t * B / J)), rtol=1e-8)
    assert tau / B == pytest.approx(853.5, abs=0.1)
    at = int(np.argmin(np.abs(t - J / B)))
    assert out["rotor_speed"][at] == pytest.approx((1 - np.exp(-1)) * tau / B, rel=1e-4)


def test_energy_balance(rotor):
    """Input work = kinetic energy + friction losses, over steps of the torque both ways with
    Coulomb, Stribeck, viscous friction and their asymmetries, and a load torque."""
    h = 1e-4
    commands = np.concatenate([np.full(20000, 1.5), np.full(20000, -1.2), np.full(10000, 0.3)])
    parameters = {
        "coulomb_friction": 0.02,
        "coulomb_asymmetry": 0.005,
        "viscous_asymmetry": 2e-5,
        "stribeck_friction": 0.01,
        "stribeck_speed": 5.0,
        "torque_asymmetry": 0.1,
    }
    out = step(
        rotor,
        commands,
        parameters,
        h,
        ("rotor_speed", "torque", "friction_torque"),
        torque=0.004,
    )
    w = np.concatenate([[0.0], out["rotor_speed"]])
    # per step, torques act on the speed's trapezoid (RK4 within the step: small error)
    mean_w = 0.5 * (w[1:] + w[:-1])
    work = np.sum(out["torque"] * mean_w * h)
    losses = np.sum((out["friction_torque"] + 0.004) * mean_w * h)
    kinetic = 0.5 * J * w[-1] ** 2
    assert work > 0.5 and kinetic > 1e-3  # the run did something
    assert work == pytest.approx(kinetic + losses, rel=2e-4)


def test_friction_and_torque_constant_differ_by_direction(rotor):
    """Terminal speeds (K_t (1 +/- c) i - (F_c +/- a)) / (B +/- b) in each direction."""
    c, fc, a, b = 0.2, 0.02, 0.008, 2e-5
    parameters = {
        "torque_asymmetry": c,
        "coulomb_friction": fc,
        "coulomb_asymmetry": a,
        "viscous_asymmetry": b,
    }
    for sign in (1.0, -1.0):
        out = step(rotor, np.full(20000, sign * 1.2), parameters)
        tau = KT * (1 + c * sign) * 1.2
        viscous = B + b * sign
        terminal = sign * (tau - (fc + a * sign)) / viscous
        t_end = 20.0 - 1e-4  # s: the rotor breaks away after the first substep
        reached = terminal * (1 - np.exp(-t_end * viscous / J))
        assert out["rotor_speed"][-1] == pytest.approx(reached, rel=1e-8)
        assert abs(reached / terminal - 1) < 3e-4


def test_the_dead_time_delays_the_torque(rotor):
    out = step(rotor, [1.0, 2.0, 3.0, 4.0], {"dead_time_steps": 2}, outputs=("torque",))
    assert list(out["torque"]) == pytest.approx([0.0, 0.0, KT * 1.0, KT * 2.0])


def test_encoder_speed_and_load_outputs(rotor):
    """The angle lies on the encoder grid, the drive's speed is its difference per step, and
    the load outputs are the true angle and speed times travel_per_rad."""
    travel = 2e-3
    out = step(
        rotor,
        np.full(500, 1.3),
        {"travel_per_rad": travel, "load_position_start": 0.5},
        outputs=(
            "motor_angle",
            "motor_speed",
            "load_position",
            "load_speed",
            "rotor_angle",
            "rotor_speed",
        ),
    )
    angle = out["motor_angle"]
    assert angle[0] == pytest.approx(0.5 / travel, abs=GRID)
    assert np.max(np.abs(angle / GRID - np.round(angle / GRID))) < 1e-6
    np.testing.assert_allclose(out["motor_speed"][1:], np.diff(angle) / 1e-3, rtol=1e-9)
    np.testing.assert_allclose(out["load_position"], travel * out["rotor_angle"], rtol=1e-12)
    assert np.max(np.abs(out["rotor_angle"] - angle)) <= GRID
    np.testing.assert_allclose(out["load_speed"], travel * out["rotor_speed"], rtol=1e-12)


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        ({"coulomb_friction": 0.01, "coulomb_asymmetry": 0.02}, "coulomb_asymmetry = 0.02"),
        ({"viscous_asymmetry": -1e-4}, "viscous_asymmetry = -0.0001"),
        ({"inertia": 0.0}, "inertia"),
    ],
)
def test_bad_values_are_refused(rotor, parameters, message):
    with pytest.raises(PlantError, match=message):
        rotor.start_run(parameters)
