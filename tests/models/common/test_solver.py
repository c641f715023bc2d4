"""The solver shared by the models (models/common/solver.h) against physics.

The lossless two-mass axis of drive2mass under a constant motor torque T from rest has a closed
form: the centre of inertia accelerates at T / (J_M + J_L) and the twist d = q_M - q_L swings
about its static value at omega_02,

    w_M(t) = T t / J + (J_L / J) T / (J_M omega_02) sin(omega_02 t),   J = J_M + J_L.

Classical RK4 through the shared substep loop must reach it with a global error of order
substep^4: halving the substep divides the error by 16. The refusals of the shared loop (a
substep too long for a model's rate, a state that leaves the finite numbers) name the model.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from twin_cosim.plant import Plant

LOSSLESS = {"backlash": 0.0, "coulomb_friction": 0.0, "viscous_friction": 0.0, "damping_ratio": 0.0}
H = 0.5e-3  # s, communication step: omega_02 * H = 0.34, RK4's error well above round-off
DURATION = 0.05  # s, about 5.5 periods of omega_02
CURRENT = 1.0  # A, from the first step on (no dead time, no current lag by default)


def motor_speed_error(plant: Plant, substeps: int) -> float:
    """Largest deviation (rad/s) of the simulated motor speed from the closed form."""
    plant.start_run({**LOSSLESS, "substeps": substeps})
    p = plant.start_values()
    j_m, j_l = p["motor_inertia"], p["load_inertia"]
    w_01 = 2 * math.pi * p["resonance_frequency"]
    w_02 = w_01 * math.sqrt(1 + j_l / j_m)  # eq. (1)
    torque = p["torque_constant"] * CURRENT
    vr_in = [plant.value_reference("current_cmd")]
    vr_out = [plant.value_reference("motor_speed")]
    n = int(round(DURATION / H))
    speed = np.empty(n)
    for k in range(n):
        plant.fmu.setReal(vr_in, [CURRENT])
        plant.fmu.doStep(k * H, H)
        speed[k] = plant.fmu.getReal(vr_out)[0]
    t = (np.arange(n) + 1) * H
    j = j_m + j_l
    exact = torque * t / j + j_l / j * torque / (j_m * w_02) * np.sin(w_02 * t)
    return float(np.max(np.abs(speed - exact)))


def test_rk4_substeps_converge_at_fourth_order_to_the_two_mass_solution(plant):
    errors = [motor_speed_error(plant, substeps) for substeps in (1, 2, 4)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((orders > 3.8) & (orders < 4.2)), (errors, orders)
    swing = 0.74 * CURRENT / (2.9e-4 * 688.19)  # rad/s, T / (J_M omega_02) of Table 1
    assert errors[-1] < 1e-4 * swing, errors


@pytest.mark.parametrize(
    ("model", "parameters", "rate"),
    [
        ("drive2mass", {"substeps": 1}, "fastest mode"),
        ("emps", {"substeps": 1, "second_mass": 30.0, "coupling_frequency": 40.0}, "coupling mode"),
    ],
)
def test_a_substep_too_long_for_a_rate_of_the_model_is_refused(model, parameters, rate):
    from fmu_build.build import build_fmu

    with Plant(build_fmu(model), model) as plant:
        plant.start_run(parameters)
        plant.messages.clear()
        with pytest.raises(FMICallException):
            plant.fmu.doStep(0.0, 0.01)
        assert any(
            f"{model}: substep 0.01 s is too long for the {rate}" in m for m in plant.messages
        ), plant.messages


def test_a_non_finite_state_is_refused_with_the_model_name(any_slave):
    """A command far beyond any drive overflows the state once its dead time (at most one 1 ms
    step by default) is over."""
    any_slave.start_run({})
    model = any_slave.description.coSimulation.modelIdentifier
    vr_in = [any_slave.vr("current_cmd")]
    with pytest.raises(FMICallException):
        for k in range(3):
            any_slave.set_reals(vr_in, [1e308])
            any_slave.do_step(k * 1e-3, 1e-3)
    assert any(
        m.startswith("[logStatusError]") and f"{model}: state became non-finite" in m
        for m in any_slave.messages
    ), any_slave.messages
