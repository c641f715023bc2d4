"""The multi-axis plant as an SSP package: an independent master (OSP libcosim) loads it and
agrees with the project's master in open loop to 1e-9 relative."""

from __future__ import annotations

import shutil
import zipfile

import numpy as np
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimManipulator import CosimManipulator
from libcosimpy.CosimObserver import CosimObserver

from twin_cosim.contour.ssp import export_ssp, open_loop, unpacked
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS
from twin_cosim.scenario import load_machine

STEPS = 1600  # 0.1 s at 62.5 us
START = {"X": 0.01, "Y": -0.005}
CURRENTS = {  # A: breakaway, reversal and back, a different pattern per axis
    "X": np.where(np.arange(STEPS) < 800, 2.5, -2.5),
    "Y": 3.0 * np.sin(np.arange(STEPS) * 2 * np.pi / 900),
}


def _in_libcosim(package, machine) -> dict[str, np.ndarray]:
    log_output_level(CosimLogLevel.WARNING)
    folder = unpacked(package)
    try:
        execution = CosimExecution.from_ssp_file(
            str(folder), round(machine.axes[0].settings.speed_period * 1e9)
        )
        index = {info.name.decode(): info.index for info in execution.slave_infos()}
        observer = CosimObserver.create_last_value()
        manipulator = CosimManipulator.create_override()
        assert execution.add_observer(observer) and execution.add_manipulator(manipulator)
        references = {}
        for name in index:
            variables = {
                v.name.decode(): v.reference for v in execution.slave_variables(index[name])
            }
            references[name] = (
                variables[CONTRACT_INPUTS[0]],
                [variables[v] for v in CONTRACT_OUTPUTS],
            )
        found = {name: [] for name in index}
        for k in range(STEPS):
            for name, (current, _) in references.items():
                assert manipulator.slave_real_values(index[name], [current], [CURRENTS[name][k]])
            assert execution.step(), execution.status()
            for name, (_, outputs) in references.items():
                found[name].append(observer.last_real_values(index[name], outputs))
        return {name: np.array(rows) for name, rows in found.items()}
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def test_the_package_holds_the_fmus_and_parameter_sets(tmp_path):
    machine = load_machine("xy_table")
    package = export_ssp(machine, tmp_path / "xy.ssp", START)
    with zipfile.ZipFile(package) as archive:
        names = set(archive.namelist())
        ssd = archive.read("SystemStructure.ssd").decode()
    assert {"SystemStructure.ssd", "resources/X.fmu", "resources/Y.fmu"} <= names
    assert {"resources/X.ssv", "resources/Y.ssv"} <= names
    assert 'name="load_position_start"><ssv:Real value="0.01"' in ssd


def test_libcosim_runs_the_package_as_the_project_master_does(tmp_path):
    machine = load_machine("xy_table")
    package = export_ssp(machine, tmp_path / "xy.ssp", START)
    theirs = _in_libcosim(package, machine)
    ours = open_loop(machine, CURRENTS, START)
    for name in ("X", "Y"):
        assert np.ptp(ours[name][:, 1]) > 1.0  # motor_speed moved: the run tests something
        scale = np.max(np.abs(ours[name]), axis=0) + 1e-300
        worst = np.max(np.abs(theirs[name] - ours[name]) / scale)
        assert worst <= 1e-9, (name, worst)
    position = CONTRACT_OUTPUTS.index("load_position")
    assert abs(theirs["X"][0, position] - 0.01) < 1e-5  # the parameter set was applied
