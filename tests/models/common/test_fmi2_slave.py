"""The shared FMI 2.0 slave: bad values, non-finite inputs and calls out of order give fmi2Error
with a logged message and never crash the process."""

from __future__ import annotations

import math

import pytest
from fmpy.fmi1 import FMICallException

from twin_cosim.plant import Plant, PlantError


def expect_error(plant: Plant, call, *args, message: str) -> None:
    plant.messages.clear()
    with pytest.raises(FMICallException):
        call(*args)
    assert any(message in m for m in plant.messages), plant.messages


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("motor_inertia", -2.9e-4, "motor_inertia = -0.00029 is invalid"),
        ("load_inertia", 0.0, "load_inertia = 0 is invalid"),
        ("resonance_frequency", 0.0, "resonance_frequency = 0 is invalid"),  # zero stiffness
        ("damping_ratio", math.nan, "damping_ratio = nan is invalid"),
        ("backlash", math.inf, "backlash = inf is invalid"),
        ("coulomb_friction", -0.1, "coulomb_friction = -0.1 is invalid"),
    ],
)
def test_bad_parameter_values_are_refused(plant, name, value, message):
    with pytest.raises(PlantError, match=message):
        plant.start_run({name: value})
    plant.start_run({})  # the instance recovers through fmi2Reset
    assert plant.fmu.getReal([plant.value_reference("motor_speed")]) == [0.0]


def test_bad_integer_parameter_is_refused(plant):
    with pytest.raises(PlantError, match="substeps = 0 is out of range"):
        plant.start_run({"substeps": 0})


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_inputs_are_refused(plant, value):
    plant.start_run({})
    expect_error(
        plant,
        plant.fmu.setReal,
        [plant.value_reference("current_cmd")],
        [value],
        message="current_cmd",
    )
    # After an error only reset, terminate or free are allowed.
    expect_error(plant, plant.fmu.doStep, 0.0, 1e-4, message="not allowed in state Error")


def test_calls_out_of_order_are_refused(plant):
    fmu = plant.fmu
    expect_error(
        plant, fmu.doStep, 0.0, 1e-4, message="fmi2DoStep: not allowed in state Instantiated"
    )
    expect_error(plant, fmu.getReal, [0], message="fmi2GetReal: not allowed in state Instantiated")
    fmu.reset()
    expect_error(plant, fmu.exitInitializationMode, message="not allowed in state Instantiated")
    fmu.reset()
    plant.start_run({})
    expect_error(
        plant,
        fmu.setReal,
        [plant.value_reference("backlash")],
        [1e-6],
        message="backlash cannot be set in state StepComplete",
    )
    fmu.reset()
    plant.start_run({})
    expect_error(
        plant,
        fmu.setReal,
        [plant.value_reference("motor_speed")],
        [1.0],
        message="motor_speed cannot be set",
    )
    fmu.reset()
    plant.start_run({})
    expect_error(plant, fmu.doStep, 0.0, -1e-4, message="h = -0.0001 is invalid")
    fmu.reset()
    plant.start_run({})
    expect_error(plant, fmu.getReal, [10_000], message="no Real variable has value reference 10000")


def test_too_long_substep_is_refused(plant):
    plant.start_run({"substeps": 1})
    expect_error(plant, plant.fmu.doStep, 0.0, 0.01, message="too long")


def test_reset_restores_start_values(plant):
    plant.start_run({"backlash": 1e-6, "load_position_start": 0.5})
    position = plant.value_reference("load_position")
    assert plant.fmu.getReal([position])[0] == pytest.approx(0.5)
    plant.start_run({})
    assert plant.fmu.getReal([position])[0] == 0.0
