"""The master compiled ahead: the same trajectories as the master compiled just in time and the
fmpy reference path (one axis, several, the measurement's injections), loaded without numba,
rebuilt when a source changes, a broken file named."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from twin_cosim.controller_set import TABLE3
from twin_cosim.cosim import AxisRun, run_axes, run_scenario
from twin_cosim.frequency.measurement import MeasurementSettings, measure
from twin_cosim.loops import ahead, kernels
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """A per-user cache of this module's own, with the loops built ahead in it."""
    folder = tmp_path_factory.mktemp("cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("TWIN_COSIM_CACHE", str(folder))
        ahead.build()
        yield folder


@pytest.fixture()
def use(monkeypatch):
    """Make this process run on the given loops (the library or the just-in-time kernels)."""

    def choose(library) -> None:
        monkeypatch.setattr(ahead, "_LOADED", [library])

    return choose


def test_a_run_is_the_same_ahead_just_in_time_and_on_the_reference_path(cache, use, plant):
    scenario = load_scenario("reference1")
    library = ahead.load()
    assert library is not None and Path(library.__file__) == ahead.library_path()
    records = {}
    for name, chosen in (("ahead", library), ("jit", kernels)):
        use(chosen)
        records[name] = run_scenario(plant, scenario, TABLE3["ga"]).to_numpy()
    reference = run_scenario(plant, scenario, TABLE3["ga"], fast=False).to_numpy()
    assert np.array_equal(records["ahead"], records["jit"])
    assert np.array_equal(records["ahead"], reference)


def test_several_axes_and_a_measurement_are_the_same_ahead(cache, use, fmu_path):
    scenario = load_scenario("reference1")
    library = ahead.load()
    grid = scenario.reference
    n = 4000
    x = ReferenceGrid(grid.period, grid.position[:n], grid.velocity[:n], grid.acceleration[:n])
    y = ReferenceGrid(x.period, -0.5 * x.position, -0.5 * x.velocity, -0.5 * x.acceleration)
    how = MeasurementSettings("speed", averages=2)
    found = {}
    with Plant(fmu_path, instance_name="X") as px, Plant(fmu_path, instance_name="Y") as py:
        axes = [
            AxisRun("X", px, x, TABLE3["ft"], scenario.settings),
            AxisRun("Y", py, y, TABLE3["ga"], scenario.settings, {"backlash": 2e-5}),
        ]
        for name, chosen in (("ahead", library), ("jit", kernels)):
            use(chosen)
            found[name] = (
                run_axes(axes),
                measure(px, scenario.tuned, scenario.settings, scenario.plant_parameters, how),
            )
        reference = run_axes(axes, fast=False)
    (axes_ahead, response_ahead), (axes_jit, response_jit) = found["ahead"], found["jit"]
    for axis in ("X", "Y"):
        ahead_record = axes_ahead[axis].position_loop.to_numpy()
        assert np.array_equal(ahead_record, axes_jit[axis].position_loop.to_numpy())
        assert np.max(np.abs(ahead_record - reference[axis].position_loop.to_numpy())) < 1e-12
    assert np.array_equal(response_ahead.response, response_jit.response)


def test_a_command_with_the_library_built_runs_without_numba(cache, tmp_path):
    code = (
        "import sys\n"
        "from twin_cosim.cli import main\n"
        f"code = main(['simulate', 'reference1', '--no-plots', '--out', {str(tmp_path)!r}])\n"
        "print(code, sorted({'numba', 'llvmlite'} & set(sys.modules)))\n"
    )
    env = {"TWIN_COSIM_CACHE": str(cache), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, env=env
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "0 []"


def test_a_changed_source_needs_a_new_library(cache, monkeypatch, tmp_path):
    built = ahead.library_path()
    copy = tmp_path / "controller.py"
    at = [source.name for source in ahead.SOURCES].index("controller.py")
    copy.write_bytes(ahead.SOURCES[at].read_bytes() + b"\n# edited\n")
    monkeypatch.setattr(ahead, "SOURCES", (*ahead.SOURCES[:at], copy, *ahead.SOURCES[at + 1 :]))
    assert ahead.library_path() != built
    assert ahead.load() is None  # not built for these sources: the loops compile just in time


def test_a_broken_library_is_named_with_how_to_rebuild(monkeypatch, tmp_path):
    monkeypatch.setenv("TWIN_COSIM_CACHE", str(tmp_path))
    path = ahead.library_path()
    path.parent.mkdir(parents=True)
    path.write_bytes(b"\x7fELF truncated")
    with pytest.raises(ahead.LoopBuildError, match=rf"{path.name}.*twin build --force"):
        ahead.load()
