"""Building drive2mass: layout, rebuild rules, validators, other importers, recompilable sources."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from fmu_build import build
from fmu_build.variable_table import load_variable_table
from twin_cosim.plant import Plant


def test_fmu_layout(fmu_path):
    names = set(zipfile.ZipFile(fmu_path).namelist())
    assert {
        "modelDescription.xml",
        "binaries/linux64/drive2mass.so",
        "documentation/index.html",
        "sources/fmi2_slave.c",
        "sources/model.c",
        "sources/model_variables.h",
        "sources/model_variable_table.h",
    } <= names
    assert not any(name.startswith("sources/fmi2") and name.endswith(".h") for name in names)


def test_fmpy_validate_reports_no_problem(fmu_path):
    assert validate_fmu(str(fmu_path)) == []


def test_fmutool_check_reports_no_problem(fmu_path):
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


def test_model_description_follows_the_variable_table(fmu_path):
    table = load_variable_table(
        build.MODELS_DIR / "drive2mass" / "variables.yaml", build.COMMON_DIR / "units.yaml"
    )
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
    assert {"N.m", "kg.m2", "rad/s"} <= {u.name for u in description.unitDefinitions}


def test_simulates_in_fmpy_simulate_fmu(fmu_path):
    current = 2.0  # A: 1.48 N.m against 0.625 N.m of Coulomb friction
    result = simulate_fmu(
        str(fmu_path),
        stop_time=0.5,
        step_size=62.5e-6,
        output_interval=0.01,
        start_values={"current_cmd": current},
    )
    travel = 0.010 / (2 * np.pi) / 1.5
    speed = result["load_speed"] / travel
    late = result["time"] >= 0.2
    slope = np.polyfit(result["time"][late], speed[late], 1)[0]
    assert slope == pytest.approx((0.74 * current - 0.625) / (2.9e-4 + 4.2e-4), rel=0.01)


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


def test_sources_in_the_fmu_recompile(fmu_path, tmp_path):
    with zipfile.ZipFile(fmu_path) as archive:
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
