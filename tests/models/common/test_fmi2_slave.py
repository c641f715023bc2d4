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


# ---------------------------------------------------------------- both models


def test_step_from_another_time_is_refused(any_plant):
    any_plant.start_run({})
    any_plant.fmu.doStep(0.0, 1e-3)
    expect_error(
        any_plant,
        any_plant.fmu.doStep,
        2e-3,
        1e-3,
        message="currentCommunicationPoint = 0.002 s is not the model time 0.001 s",
    )


def test_communication_points_within_the_tolerance_are_accepted(any_plant):
    any_plant.start_run({}, start_time=10.0)
    t = 10.0
    for _ in range(100):
        any_plant.fmu.doStep(t, 1e-3)
        t = t + 1e-3  # summed, as some masters do: a few ulp from the model's time
    any_plant.fmu.doStep(10.0 + 100 * 1e-3, 1e-3)


def test_parameters_set_in_initialization_mode_show_at_once(any_plant):
    fmu = any_plant.fmu
    position = any_plant.value_reference("load_position")
    start = any_plant.value_reference("load_position_start")
    fmu.reset()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    assert fmu.getReal([position]) == [0.0]
    fmu.setReal([start], [0.25])
    assert fmu.getReal([position])[0] == pytest.approx(0.25, abs=1e-7)
    fmu.exitInitializationMode()
    assert fmu.getReal([position])[0] == pytest.approx(0.25, abs=1e-7)


def test_inconsistent_parameters_read_in_initialization_mode_are_an_error(plant):
    fmu = plant.fmu
    fmu.reset()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.setReal([plant.value_reference("coulomb_asymmetry")], [5.0])  # > coulomb_friction
    expect_error(plant, fmu.getReal, [0], message="coulomb_asymmetry = 5 is invalid")


def test_unknown_log_category_is_refused(any_plant):
    expect_error(
        any_plant,
        any_plant.fmu.setDebugLogging,
        True,
        ["logEvents", "logEverything"],
        message='unknown log category "logEverything"',
    )


def events_of_a_stick_slip_run(plant: Plant, categories: list[str] | None) -> list[str]:
    """Log messages of category logEvents over a push and a release of the axis."""
    plant.start_run({})
    if categories is not None:
        plant.fmu.setDebugLogging(True, categories)
    plant.messages.clear()
    current = plant.value_reference("current_cmd")
    h = 1e-4
    for k in range(3000):
        plant.fmu.setReal([current], [3.0 if k < 200 else 0.0])
        plant.fmu.doStep(k * h, h)
    return [m for m in plant.messages if m.startswith("[logEvents]")]


def test_stick_slip_events_are_logged_when_asked_and_only_then(any_plant):
    assert events_of_a_stick_slip_run(any_plant, None) == []
    events = events_of_a_stick_slip_run(any_plant, ["logEvents"])
    assert any("breaks away" in m for m in events), events
    assert any("sticks" in m for m in events), events
    assert events_of_a_stick_slip_run(any_plant, ["logStatusError"]) == events  # still on
    any_plant.fmu.setDebugLogging(False, ["logEvents"])
    assert events_of_a_stick_slip_run(any_plant, None) == []


def test_step_limits_are_logged_as_events(any_plant):
    any_plant.fmu.setDebugLogging(True, [])
    any_plant.start_run({})
    assert any(m.startswith("[logEvents]") and "substep limit" in m for m in any_plant.messages)


def test_errors_are_logged_with_logging_off(any_plant):
    any_plant.fmu.setDebugLogging(False, [])
    any_plant.start_run({})
    expect_error(any_plant, any_plant.fmu.doStep, 0.0, -1.0, message="[logStatusError]")


def test_outputs_change_with_an_input_only_when_they_declare_it(any_plant):
    """After a step from rest (the axis stuck), set each input anew and read every output: those
    that change are exactly those whose ModelStructure dependencies list the input."""
    description = any_plant.description
    outputs = [u.variable for u in description.outputs]
    declared = {u.variable.name: {d.name for d in u.dependencies} for u in description.outputs}
    vr_out = [v.valueReference for v in outputs]
    for name, value in (("current_cmd", 0.1), ("disturbance_torque", 0.05)):
        any_plant.start_run({})
        any_plant.fmu.doStep(0.0, 1e-4)
        before = any_plant.fmu.getReal(vr_out)
        any_plant.fmu.setReal([any_plant.value_reference(name)], [value])
        after = any_plant.fmu.getReal(vr_out)
        changed = {v.name for v, a, b in zip(outputs, after, before, strict=True) if a != b}
        assert changed == {v.name for v in outputs if name in declared[v.name]}, name
