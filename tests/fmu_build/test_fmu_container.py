"""Both FMI 3.0 FMUs in a second, independent importer: the FMU container of
fmu-manipulation-toolbox (PyPI). Its C runtime loads the embedded FMU's binary, sets the start
values, initialises and steps it through the fmi3 functions; fmpy runs the container (itself an
FMI 2.0 FMU) as a user would. Its outputs agree with fmpy's own FMU3Slave run to 1e-13 of each
output's range. (OSP libcosim, the FMI 2.0 FMUs' second importer in test_libcosim.py, refuses an
FMI 3.0 FMU: "Unsupported FMI version".)"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fmu_build.build import CACHE_ENV, build_fmu
from tests.fmu_build.conftest import MODELS
from tests.models.conftest import RUNS, STEPS, Fmi3Slave, outputs_of_a_run
from twin_cosim.plant import Plant


def build_container(fmu_path: Path, folder: Path, step: float, parameters: dict) -> Path:
    """A container FMU around ``fmu_path`` in ``folder``: both inputs exposed, the parameters
    as start values of the embedded FMU, every output exposed (the container's default)."""
    shutil.copy(fmu_path, folder / fmu_path.name)
    rules = [
        "rule;from_fmu;from_port;to_fmu;to_port",
        f"FMU;{fmu_path.name};;;",
        f"INPUT;;current_cmd;{fmu_path.name};current_cmd",
        f"INPUT;;disturbance_torque;{fmu_path.name};disturbance_torque",
        *(f"START;{fmu_path.name};{name};{value};" for name, value in parameters.items()),
    ]
    (folder / "plant.csv").write_text("\n".join(rules) + "\n")
    result = subprocess.run(
        [
            str(Path(sys.executable).with_name("fmucontainer")),
            "-container",
            f"plant.csv:{step!r}",
            "-fmu-directory",
            str(folder),
        ],
        capture_output=True,
        text=True,
        cwd=folder,
        timeout=300,
    )
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    return folder / "plant.fmu"


def run_in_container(container: Path, model: str, outputs: list[str]) -> np.ndarray:
    """The run of outputs_of_a_run (tests/models/conftest.py) stepped through the container, an
    FMI 2.0 FMU that offers the plant contract, in the twin's Plant: each output after each
    step."""
    h, _, command = RUNS[model]
    with Plant(container, "container") as plant:
        plant.start_run({})
        vr_in = [plant.value_reference("current_cmd"), plant.value_reference("disturbance_torque")]
        vr_out = [plant.value_reference(name) for name in outputs]
        rows = []
        for k in range(STEPS):
            plant.fmu.setReal(vr_in, [command(k), 0.0 if k < STEPS // 2 else 0.05])
            plant.fmu.doStep(k * h, h)
            rows.append(plant.fmu.getReal(vr_out))
    return np.array(rows)


@pytest.mark.parametrize("model", MODELS)
def test_the_fmu_container_runs_the_fmi3_fmu_as_fmpy_does(model, tmp_path, monkeypatch):
    h, parameters, _ = RUNS[model]
    slave = Fmi3Slave(model)
    try:
        reference = outputs_of_a_run(slave, model)
    finally:
        slave.close()
    outputs = [u.variable.name for u in slave.description.outputs]
    container = build_container(build_fmu(model, fmi_version=3), tmp_path, h, parameters)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))  # the container's extraction
    embedded = run_in_container(container, model, outputs)
    assert np.ptp(reference[:, outputs.index("motor_speed")]) > 0.0  # the run tests something
    assert embedded[0, outputs.index("load_position")] == pytest.approx(
        parameters["load_position_start"], abs=2e-7
    )  # the start values reached the embedded FMU
    scale = np.ptp(reference, axis=0) + 1e-300
    assert np.max(np.abs(embedded - reference) / scale) <= 1e-13
