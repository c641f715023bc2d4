"""What only the FMI 3.0 slave (models/common/fmi3_slave.c) has: trajectories equal to the FMI 2.0
slave's, fmi3DoStep's outputs, the independent variable time, value counts, the event mode, the
instantiation token, and the functions it does not offer (the shared behaviour: test_slave.py)."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Model, FMU3Slave

from fmu_build.build import build_fmu
from tests.models.common.test_slave import expect_error
from tests.models.conftest import MODELS, Fmi2Slave, Fmi3Slave, outputs_of_a_run
from twin_cosim.plant import extracted_fmu


@pytest.fixture()
def fmi3():
    """Makes FMI 3.0 slaves (model, event_mode_used=False) and frees them after the test."""
    made = []

    def make(model: str, event_mode_used: bool = False) -> Fmi3Slave:
        made.append(Fmi3Slave(model, event_mode_used))
        return made[-1]

    yield make
    for slave in made:
        slave.close()


@pytest.mark.parametrize("model", MODELS)
def test_trajectories_equal_the_fmi2_slaves(model, fmi3):
    """The same command sequence stepped through both versions' FMUs gives the same outputs to
    1e-12 of each output's range, step by step."""
    fmi2, slave = Fmi2Slave(model), fmi3(model)
    try:
        reference = outputs_of_a_run(fmi2, model)
    finally:
        fmi2.close()
    outputs = outputs_of_a_run(slave, model)
    names = [u.variable.name for u in slave.description.outputs]
    assert names == [u.variable.name for u in fmi2.description.outputs]
    speed = reference[:, names.index("motor_speed")]
    assert speed.max() > 0.0 > speed.min()  # the run drove the axis both ways
    scale = np.ptp(reference, axis=0) + 1e-300
    assert np.max(np.abs(outputs - reference) / scale) <= 1e-12


def test_do_step_reports_a_whole_step_and_time_follows(fmi3):
    slave = fmi3("drive2mass")
    time = slave.description.modelVariables[0]
    assert (time.name, time.causality) == ("time", "independent")
    slave.start_run({}, start_time=2.0)
    assert slave.get_reals([time.valueReference]) == [2.0]
    assert slave.do_step(2.0, 0.001) == (False, False, False, 2.001)
    assert slave.get_reals([slave.vr("motor_speed"), time.valueReference])[1] == 2.001
    expect_error(
        slave,
        slave.set_reals,
        [time.valueReference],
        [3.0],
        message="fmi3SetFloat64: time cannot be set",
    )


def test_value_counts_must_match_the_references(fmi3):
    """Every variable is a scalar: nValues must equal nValueReferences."""
    slave = fmi3("emps")
    slave.start_run({})
    refs = [slave.vr("motor_speed"), slave.vr("load_position")]
    expect_error(
        slave,
        slave.fmu.getFloat64,
        refs,
        3,
        message="fmi3GetFloat64: 3 values for 2 value references",
    )


def test_int32_variables_are_not_float64(fmi3):
    slave = fmi3("drive2mass")
    slave.start_run({"substeps": 7})
    substeps = slave.vr("substeps")
    assert slave.fmu.getInt32([substeps]) == [7]
    expect_error(
        slave,
        slave.get_reals,
        [substeps],
        message=f"fmi3GetFloat64: no Float64 variable has value reference {substeps}",
    )


def test_event_mode_when_the_importer_asks_for_it(fmi3):
    """With eventModeUsed the instance leaves initialization into event mode, where inputs may be
    set and nothing needs updating, and steps only in step mode; the run is the same."""
    h = 1e-3
    plain, evented = fmi3("emps"), fmi3("emps", event_mode_used=True)
    plain.start_run({})
    evented.start_run({})
    current = evented.vr("current_cmd")
    expect_error(
        evented, evented.do_step, 0.0, h, message="fmi3DoStep: not allowed in state EventMode"
    )
    outputs = []
    for slave in (plain, evented):
        for k in range(200):
            if slave is evented:
                if k > 0:
                    slave.fmu.enterEventMode()
                slave.set_reals([current], [3.0 if k < 100 else -1.0])
                assert slave.fmu.updateDiscreteStates() == (False,) * 5 + (0.0,)
                slave.fmu.enterStepMode()
            else:
                slave.set_reals([current], [3.0 if k < 100 else -1.0])
            slave.do_step(k * h, h)
        outputs.append(slave.get_reals([slave.vr("load_position"), slave.vr("load_speed")]))
    assert outputs[0] == outputs[1]
    expect_error(
        plain,
        plain.fmu.enterEventMode,
        message="fmi3EnterEventMode: the instance was created with eventModeUsed = false",
    )
    expect_error(
        plain, plain.fmu.enterStepMode, message="fmi3EnterStepMode: not allowed in state StepMode"
    )


def refused_instantiation(fmu: FMU3Slave | FMU3Model) -> list[str]:
    """What the FMU logs when ``fmu.instantiate`` fails, as fmpy says it does."""
    messages = []
    with pytest.raises(Exception, match="Failed to instantiate FMU"):
        fmu.instantiate(logMessage=lambda _env, _status, _cat, m: messages.append(m.decode()))
    return messages


def test_a_wrong_instantiation_token_is_refused(fmi3):
    fmu = fmi3("drive2mass").fmu
    other = FMU3Slave(
        guid="{00000000-0000-0000-0000-000000000000}",
        unzipDirectory=fmu.unzipDirectory,
        modelIdentifier="drive2mass",
        instanceName="other",
    )
    assert refused_instantiation(other) == [
        "fmi3InstantiateCoSimulation: instantiationToken does not match this binary"
    ]


def test_only_co_simulation_is_offered():
    fmu_path = build_fmu("emps", fmi_version=3)
    exchange = FMU3Model(
        guid=read_model_description(str(fmu_path)).guid,
        unzipDirectory=str(extracted_fmu(fmu_path)),
        modelIdentifier="emps",
    )
    assert refused_instantiation(exchange) == [
        "fmi3InstantiateModelExchange: only co-simulation is supported"
    ]


def test_functions_not_offered_say_so(fmi3):
    slave = fmi3("drive2mass")
    slave.start_run({})
    assert slave.fmu.getBoolean([]) == []  # no Boolean variables: nothing asked, nothing wrong
    expect_error(
        slave, slave.fmu.getFMUState, message="fmi3GetFMUState: not supported by this model"
    )
    expect_error(
        slave,
        slave.fmu.getBoolean,
        [0],
        message="fmi3GetBoolean: the model has no variables of this type",
    )


def test_two_instances_are_independent(fmi3):
    """Interleaved steps of two instances give each the trajectory it has alone."""
    first, second = fmi3("drive2mass"), fmi3("drive2mass")
    h = 62.5e-6

    def speed_after_step(slave: Fmi3Slave, current: float, k: int) -> float:
        slave.set_reals([slave.vr("current_cmd")], [current])
        slave.do_step(k * h, h)
        return slave.get_reals([slave.vr("motor_speed")])[0]

    first.start_run({"backlash": 0.0})
    alone = [speed_after_step(first, 1.5, k) for k in range(400)]
    first.start_run({"backlash": 0.0})
    second.start_run({"coulomb_friction": 0.0})
    together = [
        (speed_after_step(first, 1.5, k), speed_after_step(second, -0.5, k)) for k in range(400)
    ]
    assert [a for a, _ in together] == alone
    assert together[-1][1] < 0 < together[-1][0]
