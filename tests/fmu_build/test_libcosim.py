"""Both FMUs in a second, independent importer: OSP libcosim (libcosimpy from PyPI) runs them as
a user drops them into it, and its results agree with fmpy's to about 1e-13 relative."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver
from libcosimpy.CosimSlave import CosimLocalSlave

from fmu_build.build import build_fmu
from twin_cosim.plant import Plant

STEPS = 400
# Per model: step (ns, libcosim's time unit), parameters set before initialization, and the
# input sequence (current_cmd per step) that drives the axis through breakaway and reversal.
RUNS = {
    "drive2mass": (
        62_500,
        {"load_position_start": 0.02, "noise_amplitude_1": 1e-7, "dead_time_steps": 2},
        lambda k: 2.5 if k < 200 else -2.5,
    ),
    "emps": (1_000_000, {"load_position_start": 0.1, "dead_time_steps": 2}, lambda k: 3.0 - k / 50),
    "hsm150": (
        1_000_000,
        {"load_position_start": 0.1, "coulomb_friction": 0.03, "dead_time_steps": 2},
        lambda k: 1.5 - k / 100,
    ),
}


def run_in_libcosim(fmu_path, step_ns: int, parameters, command) -> np.ndarray:
    """Every output after every step, as libcosim's last-value observer reports them."""
    log_output_level(CosimLogLevel.WARNING)
    description = read_model_description(str(fmu_path))
    by_name = {v.name: v for v in description.modelVariables}
    outputs = [v.valueReference for v in description.modelVariables if v.causality == "output"]
    execution = CosimExecution.from_step_size(step_ns)
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmu_path), instance_name="p"))
    observer = CosimObserver.create_last_value()
    manipulator = CosimManipulator.create_override()
    assert execution.add_observer(observer) and execution.add_manipulator(manipulator)
    for name, value in parameters.items():
        variable = by_name[name]
        if variable.type == "Integer":
            assert execution.integer_initial_value(index, variable.valueReference, int(value))
        else:
            assert execution.real_initial_value(index, variable.valueReference, float(value))
    rows = []
    for k in range(STEPS):
        assert manipulator.slave_real_values(
            index, [by_name["current_cmd"].valueReference], [command(k)]
        )
        assert execution.step(), f"libcosim step {k} failed: {execution.status()}"
        rows.append(observer.last_real_values(index, outputs))
    return np.array(rows)


def run_in_fmpy(fmu_path, step_ns: int, parameters, command) -> np.ndarray:
    """The same run through fmpy: set the command, doStep(k h, h), read every output."""
    h = step_ns * 1e-9
    with Plant(fmu_path) as plant:
        plant.start_run(parameters)
        outputs = [
            v.valueReference for v in plant.description.modelVariables if v.causality == "output"
        ]
        current = plant.value_reference("current_cmd")
        rows = []
        for k in range(STEPS):
            plant.fmu.setReal([current], [command(k)])
            plant.fmu.doStep(k * h, h)
            rows.append(plant.fmu.getReal(outputs))
    return np.array(rows)


def test_libcosim_runs_the_fmu_as_fmpy_does(model_fmu):
    model, fmu_path = model_fmu
    step_ns, parameters, command = RUNS[model]
    cosim = run_in_libcosim(fmu_path, step_ns, parameters, command)
    reference = run_in_fmpy(fmu_path, step_ns, parameters, command)
    assert np.ptp(reference[:, 1]) > 0.0  # motor_speed moved: the run tests something
    scale = np.max(np.abs(reference), axis=0) + 1e-300
    worst = np.max(np.abs(cosim - reference) / scale)
    assert worst <= 1e-13, worst


@pytest.mark.parametrize("model", ["drive2mass", "emps", "hsm150"])
def test_libcosim_sees_parameters_set_before_initialization(model):
    fmu_path = build_fmu(model)
    step_ns, parameters, _ = RUNS[model]
    cosim = run_in_libcosim(fmu_path, step_ns, parameters, lambda k: 0.0)
    description = read_model_description(str(fmu_path))
    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    position = cosim[:, outputs.index("load_position")]
    assert position[0] == pytest.approx(parameters["load_position_start"], abs=2e-7)
