"""Building the FMUs: layout, rebuild rules, validators, other importers, recompilable sources,
the generated model description (dependencies, log categories, default experiment)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from fmu_build import build, generate
from fmu_build.variable_table import VariableTable, load_variable_table
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model


def test_fmu_layout(model_fmu):
    model, fmu_path = model_fmu
    names = set(zipfile.ZipFile(fmu_path).namelist())
    assert {
        "modelDescription.xml",
        f"binaries/linux64/{model}.so",
        "documentation/index.html",
        "sources/fmi2_slave.c",
        "sources/model.c",
        "sources/model_variables.h",
        "sources/model_variable_table.h",
    } <= names
    assert not any(name.startswith("sources/fmi2") and name.endswith(".h") for name in names)


def test_fmpy_validate_reports_no_problem(model_fmu):
    assert validate_fmu(str(model_fmu[1])) == []


def test_fmutool_check_reports_no_problem(model_fmu):
    fmu_path = model_fmu[1]
    result = subprocess.run(
        [str(Path(sys.executable).with_name("fmutool")), "-input", str(fmu_path), "-check"],
        capture_output=True,
        text=True,
    )
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert "compliant with FMI-2.0" in output
    assert "No semantic error" in output
    assert "ERROR" not in output.replace("logStatusError", "")


def load_table(model: str) -> VariableTable:
    return load_variable_table(
        build.MODELS_DIR / model / "variables.yaml", build.COMMON_DIR / "units.yaml"
    )


def test_model_description_follows_the_variable_table(model_fmu):
    model, fmu_path = model_fmu
    table = load_table(model)
    description = read_model_description(str(fmu_path))
    by_name = {v.name: v for v in description.modelVariables}
    assert set(by_name) == {v.name for v in table.variables}
    for v in table.variables:
        xml = by_name[v.name]
        assert (xml.valueReference, xml.causality, xml.type) == (
            v.value_reference,
            v.causality,
            v.type,
        )
        if v.type == "Real":
            assert (xml.unit or "1") == v.unit
    outputs = [u.variable.name for u in description.outputs]
    assert outputs == [v.name for v in table.variables if v.causality == "output"]
    units = {u.name: u.baseUnit for u in description.unitDefinitions}
    for name, unit in units.items():
        for base in ("kg", "m", "s", "A", "rad"):
            assert getattr(unit, base) == table.units[name].get(base, 0), (name, base)


def test_outputs_declare_their_direct_inputs(model_fmu):
    model, fmu_path = model_fmu
    table = load_table(model)
    description = read_model_description(str(fmu_path))
    assert description.outputs, "no ModelStructure outputs"
    for unknown in description.outputs:
        declared = table.by_name(unknown.variable.name).depends_on
        # fmpy reads dependencies="" as an empty list: the output depends on no input
        assert unknown.dependencies is not None, unknown.variable.name
        assert [d.name for d in unknown.dependencies] == list(declared)
        assert all(d.causality == "input" for d in unknown.dependencies)
    state_outputs = [u for u in description.outputs if not u.dependencies]
    assert {"motor_angle", "motor_speed", "load_position", "load_speed"} <= {
        u.variable.name for u in state_outputs
    }


def test_default_experiment_step_is_the_sample_period(model_fmu):
    model, fmu_path = model_fmu
    description = read_model_description(str(fmu_path))
    sample_period = next(v for v in description.modelVariables if v.name == "sample_period")
    assert float(description.defaultExperiment.stepSize) == float(sample_period.start)
    assert float(sample_period.start) == {"drive2mass": 62.5e-6, "emps": 1e-3}[model]


def test_log_categories_are_declared(model_fmu):
    root = ElementTree.parse(zipfile.ZipFile(model_fmu[1]).open("modelDescription.xml")).getroot()
    names = [c.get("name") for c in root.iter("Category")]
    assert names == [name for name, _ in generate.LOG_CATEGORIES]
    assert {"logEvents", "logStatusError"} <= set(names)


def test_simulates_in_fmpy_simulate_fmu(fmu_path):
    current = 2.0  # A: 1.48 N.m against 0.625 N.m of Coulomb friction
    result = simulate_fmu(
        str(fmu_path),
        stop_time=0.5,
        step_size=62.5e-6,
        output_interval=0.01,
        start_values={"current_cmd": current},
    )
    travel = plant_model("drive2mass").drive_facts()["travel_per_rad"]
    speed = result["load_speed"] / travel
    late = result["time"] >= 0.2
    slope = np.polyfit(result["time"][late], speed[late], 1)[0]
    assert slope == pytest.approx((0.74 * current - 0.625) / (2.9e-4 + 4.2e-4), rel=0.01)


def test_emps_simulates_in_fmpy_at_its_default_step():
    """simulate_fmu without a step size uses DefaultExperiment's (the 1 ms sample period); 3 V
    drives the axis to the speed where viscous friction takes the rest of the force."""
    result = simulate_fmu(
        str(build.build_fmu("emps")), stop_time=4.0, start_values={"current_cmd": 3.0}
    )
    gain, coulomb, offset, viscous = 35.15065188, 20.3935, -3.1648, 203.5034  # N/V, N, N, N.s/m
    terminal = (gain * 3.0 - coulomb - offset) / viscous  # m/s
    assert result["load_speed"][-1] == pytest.approx(terminal, rel=1e-3)


def step_motor_speed(plant: Plant, current: float, k: int, h: float = 62.5e-6) -> float:
    """One step of ``h`` (s) from t = k h with ``current`` (A); the motor speed after it (rad/s)."""
    plant.fmu.setReal([plant.value_reference("current_cmd")], [current])
    plant.fmu.doStep(k * h, h)
    return plant.fmu.getReal([plant.value_reference("motor_speed")])[0]


def test_two_instances_are_independent(fmu_path):
    with Plant(fmu_path, "a") as a, Plant(fmu_path, "b") as b:
        a.start_run({"backlash": 0.0})
        solo = [step_motor_speed(a, 1.5, k) for k in range(400)]
        a.start_run({"backlash": 0.0})
        b.start_run({"coulomb_friction": 0.0})
        interleaved_a, interleaved_b = [], []
        for k in range(400):
            interleaved_a.append(step_motor_speed(a, 1.5, k))
            interleaved_b.append(step_motor_speed(b, -0.5, k))
        assert interleaved_a == solo
        assert interleaved_b[-1] < 0 < interleaved_a[-1]


def test_sources_in_the_fmu_recompile(model_fmu, tmp_path):
    with zipfile.ZipFile(model_fmu[1]) as archive:
        archive.extractall(tmp_path)
    sources = sorted((tmp_path / "sources").glob("*.c"))
    subprocess.run(
        [
            "gcc",
            *build.CFLAGS,
            f"-I{tmp_path / 'sources'}",
            f"-I{build.fmi_headers_dir()}",
            "-o",
            str(tmp_path / "again.so"),
            *map(str, sources),
            "-lm",
        ],
        check=True,
    )
    assert (tmp_path / "again.so").stat().st_size > 0


@pytest.fixture()
def model_copy(tmp_path, monkeypatch) -> Path:
    """A private copy of models/ so that tests may edit sources."""
    models = tmp_path / "models"
    shutil.copytree(build.MODELS_DIR, models)
    monkeypatch.setattr(build, "MODELS_DIR", models)
    monkeypatch.setattr(build, "COMMON_DIR", models / "common")
    return models


def test_rebuilds_only_when_sources_change(model_copy, tmp_path):
    out = tmp_path / "out"
    first = build.build_fmu("drive2mass", out)
    stamp = first.stat().st_mtime_ns
    assert build.build_fmu("drive2mass", out).stat().st_mtime_ns == stamp
    model_c = model_copy / "drive2mass" / "model.c"
    model_c.write_text(model_c.read_text() + "\n/* edited */\n")
    assert build.build_fmu("drive2mass", out).stat().st_mtime_ns != stamp


def test_compiler_errors_are_reported(model_copy, tmp_path):
    model_c = model_copy / "drive2mass" / "model.c"
    model_c.write_text(model_c.read_text() + "\nstatic int unused_variable;\n")
    with pytest.raises(build.BuildError, match="compiling drive2mass failed"):
        build.build_fmu("drive2mass", tmp_path / "out")


def test_unknown_model_is_an_error():
    with pytest.raises(build.BuildError, match="unknown model 'nope'"):
        build.build_fmu("nope")


@pytest.mark.parametrize("debug_logging", [True, False])
def test_events_reach_fmpys_logger_only_with_debug_logging(model_fmu, debug_logging):
    """fmpy instantiates with loggingOn = debug_logging and passes our logger callback; a push
    then a release of the axis logs its breakaway and its sticking only when logging is on."""
    messages = []

    def logger(_environment, _instance, _status, category, message):
        messages.append((category.decode(), message.decode()))

    signal = np.array(
        [(0.0, 3.0), (0.02, 3.0), (0.02, 0.0), (0.4, 0.0)],
        dtype=[("time", float), ("current_cmd", float)],
    )
    simulate_fmu(
        str(model_fmu[1]),
        stop_time=0.4,
        step_size=1e-4,
        input=signal,
        debug_logging=debug_logging,
        logger=logger,
    )
    events = [m for c, m in messages if c == "logEvents"]
    if debug_logging:
        assert any("breaks away" in m for m in events), messages
        assert any("sticks" in m for m in events), messages
    else:
        assert events == []


def test_default_builds_go_to_a_cache_keyed_by_the_sources(model_copy, tmp_path, monkeypatch):
    monkeypatch.setenv(build.CACHE_ENV, str(tmp_path / "cache"))
    first = build.build_fmu("drive2mass")
    assert first.parent.parent == tmp_path / "cache" / "fmu"
    assert first.parent.name == f"drive2mass-{build.fingerprint('drive2mass')[:16]}"
    model_c = model_copy / "drive2mass" / "model.c"
    model_c.write_text(model_c.read_text() + "\n/* edited */\n")
    second = build.build_fmu("drive2mass")
    assert second != first and first.is_file() and second.is_file()
    assert not list((tmp_path / "cache").rglob(".*"))  # no temporary file left behind


def test_cache_follows_xdg_when_no_override(monkeypatch, tmp_path):
    monkeypatch.delenv(build.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert build.cache_dir() == tmp_path / "twin-cosim"


def test_a_build_says_so_only_when_it_compiles(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(build.CACHE_ENV, str(tmp_path))
    path = build.build_fmu("drive2mass", announce=True)
    assert "building the drive2mass FMU" in capsys.readouterr().err
    assert build.build_fmu("drive2mass", announce=True) == path
    assert capsys.readouterr().err == ""


def test_concurrent_builds_share_the_cache(tmp_path):
    """Four processes build the same model into one empty cache at once: all get a valid FMU."""
    script = "from fmu_build.build import build_fmu; print(build_fmu('drive2mass'))"
    env = {**os.environ, build.CACHE_ENV: str(tmp_path)}
    processes = [
        subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, env=env, text=True)
        for _ in range(4)
    ]
    paths = {process.communicate(timeout=300)[0].strip() for process in processes}
    assert all(process.returncode == 0 for process in processes)
    assert len(paths) == 1
    (path,) = paths
    assert validate_fmu(path) == []
    assert [p.name for p in Path(path).parent.iterdir()] == ["drive2mass.fmu"]
