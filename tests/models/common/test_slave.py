"""The slave shared by both FMI versions (models/common/slave.c), through each version's API: bad
values, non-finite inputs and calls out of order give an error status (fmi2Error, fmi3Error) with
a logged message and never crash the process."""

from __future__ import annotations

import math

import pytest
from fmpy.fmi1 import FMICallException

from tests.models.conftest import BREAKAWAY, Fmi2Slave, Fmi3Slave
from twin_cosim.plant import PlantError

Slave = Fmi2Slave | Fmi3Slave


def expect_error(slave: Slave, call, *args, message: str) -> None:
    slave.messages.clear()
    with pytest.raises(FMICallException):
        call(*args)
    assert any(message in m for m in slave.messages), slave.messages


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
def test_bad_parameter_values_are_refused(slave, name, value, message):
    with pytest.raises(PlantError, match=message):
        slave.start_run({name: value})
    slave.start_run({})  # the instance recovers through a reset
    assert slave.get_reals([slave.vr("motor_speed")]) == [0.0]


def test_bad_integer_parameter_is_refused(slave):
    with pytest.raises(PlantError, match="substeps = 0 is out of range"):
        slave.start_run({"substeps": 0})


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_inputs_are_refused(slave, value):
    slave.start_run({})
    expect_error(slave, slave.set_reals, [slave.vr("current_cmd")], [value], message="current_cmd")
    # After an error only reset, terminate or free are allowed.
    expect_error(slave, slave.do_step, 0.0, 1e-4, message="not allowed in state Error")


def test_calls_out_of_order_are_refused(slave):
    fmu = slave.fmu
    do_step, get_real = slave.function("DoStep"), slave.function("GetReal")
    expect_error(
        slave, slave.do_step, 0.0, 1e-4, message=f"{do_step}: not allowed in state Instantiated"
    )
    expect_error(
        slave, slave.get_reals, [0], message=f"{get_real}: not allowed in state Instantiated"
    )
    fmu.reset()
    expect_error(slave, fmu.exitInitializationMode, message="not allowed in state Instantiated")
    fmu.reset()
    slave.start_run({})
    expect_error(
        slave,
        slave.set_reals,
        [slave.vr("backlash")],
        [1e-6],
        message=f"backlash cannot be set in state {slave.step_state}",
    )
    fmu.reset()
    slave.start_run({})
    expect_error(
        slave,
        slave.set_reals,
        [slave.vr("motor_speed")],
        [1.0],
        message="motor_speed cannot be set",
    )
    fmu.reset()
    slave.start_run({})
    expect_error(slave, slave.do_step, 0.0, -1e-4, message="h = -0.0001 is invalid")
    fmu.reset()
    slave.start_run({})
    expect_error(
        slave,
        slave.get_reals,
        [10_000],
        message=f"no {slave.real_type} variable has value reference 10000",
    )


def test_too_long_substep_is_refused(slave):
    slave.start_run({"substeps": 1})
    expect_error(slave, slave.do_step, 0.0, 0.01, message="too long")


def test_reset_restores_start_values(slave):
    slave.start_run({"backlash": 1e-6, "load_position_start": 0.5})
    position = slave.vr("load_position")
    assert slave.get_reals([position])[0] == pytest.approx(0.5)
    slave.start_run({})
    assert slave.get_reals([position])[0] == 0.0


# ---------------------------------------------------------------- both models


def test_step_from_another_time_is_refused(any_slave):
    any_slave.start_run({})
    any_slave.do_step(0.0, 1e-3)
    expect_error(
        any_slave,
        any_slave.do_step,
        2e-3,
        1e-3,
        message="currentCommunicationPoint = 0.002 s is not the model time 0.001 s",
    )


def test_communication_points_within_the_tolerance_are_accepted(any_slave):
    any_slave.start_run({}, start_time=10.0)
    t = 10.0
    for _ in range(100):
        any_slave.do_step(t, 1e-3)
        t = t + 1e-3  # summed, as some masters do: a few ulp from the model's time
    any_slave.do_step(10.0 + 100 * 1e-3, 1e-3)


def test_parameters_set_in_initialization_mode_show_at_once(any_slave):
    fmu = any_slave.fmu
    position = any_slave.vr("load_position")
    start = any_slave.vr("load_position_start")
    fmu.reset()
    any_slave.enter_initialization(start_time=0.0)
    assert any_slave.get_reals([position]) == [0.0]
    any_slave.set_reals([start], [0.25])
    assert any_slave.get_reals([position])[0] == pytest.approx(0.25, abs=1e-7)
    fmu.exitInitializationMode()
    assert any_slave.get_reals([position])[0] == pytest.approx(0.25, abs=1e-7)


def test_inconsistent_parameters_read_in_initialization_mode_are_an_error(slave):
    slave.fmu.reset()
    slave.enter_initialization(start_time=0.0)
    slave.set_reals([slave.vr("coulomb_asymmetry")], [5.0])  # > coulomb_friction
    expect_error(slave, slave.get_reals, [0], message="coulomb_asymmetry = 5 is invalid")


def test_unknown_log_category_is_refused(any_slave):
    expect_error(
        any_slave,
        any_slave.fmu.setDebugLogging,
        True,
        ["logEvents", "logEverything"],
        message='unknown log category "logEverything"',
    )


def events_of_a_stick_slip_run(slave: Slave, categories: list[str] | None) -> list[str]:
    """Log messages of category logEvents over a push and a release of the axis."""
    slave.start_run(BREAKAWAY.get(slave.model, {}))
    if categories is not None:
        slave.fmu.setDebugLogging(True, categories)
    slave.messages.clear()
    current = slave.vr("current_cmd")
    h = 1e-4
    for k in range(3000):
        slave.set_reals([current], [3.0 if k < 200 else 0.0])
        slave.do_step(k * h, h)
    return [m for m in slave.messages if m.startswith("[logEvents]")]


def test_stick_slip_events_are_logged_when_asked_and_only_then(any_slave):
    assert events_of_a_stick_slip_run(any_slave, None) == []
    events = events_of_a_stick_slip_run(any_slave, ["logEvents"])
    assert any("breaks away" in m for m in events), events
    assert any("sticks" in m for m in events), events
    assert events_of_a_stick_slip_run(any_slave, ["logStatusError"]) == events  # still on
    any_slave.fmu.setDebugLogging(False, ["logEvents"])
    assert events_of_a_stick_slip_run(any_slave, None) == []


def test_step_limits_are_logged_as_events(any_slave):
    any_slave.fmu.setDebugLogging(True, [])
    any_slave.start_run({})
    assert any(m.startswith("[logEvents]") and "substep limit" in m for m in any_slave.messages)


def test_errors_are_logged_with_logging_off(any_slave):
    any_slave.fmu.setDebugLogging(False, [])
    any_slave.start_run({})
    expect_error(any_slave, any_slave.do_step, 0.0, -1.0, message="[logStatusError]")


def test_outputs_change_with_an_input_only_when_they_declare_it(any_slave):
    """After a step from rest (the axis stuck), set each input anew and read every output: those
    that change are exactly those whose ModelStructure dependencies list the input."""
    description = any_slave.description
    outputs = [u.variable for u in description.outputs]
    declared = {u.variable.name: {d.name for d in u.dependencies} for u in description.outputs}
    vr_out = [v.valueReference for v in outputs]
    for name, value in (("current_cmd", 0.1), ("disturbance_torque", 0.05)):
        any_slave.start_run(BREAKAWAY.get(any_slave.model, {}))
        any_slave.do_step(0.0, 1e-4)
        before = any_slave.get_reals(vr_out)
        any_slave.set_reals([any_slave.vr(name)], [value])
        after = any_slave.get_reals(vr_out)
        changed = {v.name for v, a, b in zip(outputs, after, before, strict=True) if a != b}
        assert changed == {v.name for v in outputs if name in declared[v.name]}, name
