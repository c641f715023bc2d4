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
