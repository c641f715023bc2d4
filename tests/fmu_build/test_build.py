"""Building the FMUs of both FMI versions: layout, rebuild rules and the cache, validators,
simulation in fmpy, recompilable sources, events through fmpy's logger (the generated model
description: test_model_description.py)."""

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
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model


def test_fmu_layout(any_fmu):
    model, version, fmu_path = any_fmu
    names = set(zipfile.ZipFile(fmu_path).namelist())
    assert {
        "modelDescription.xml",
        build.binary_path(model, version),
        "documentation/index.html",
        f"sources/fmi{version}_slave.c",
        "sources/slave.c",
        "sources/model.c",
        "sources/model_variables.h",
        "sources/model_variable_table.h",
    } <= names
    assert (
        build.binary_path(model, version)
        == {
            2: f"binaries/linux64/{model}.so",
            3: f"binaries/x86_64-linux/{model}.so",
        }[version]
    )
    assert ("sources/buildDescription.xml" in names) == (version == 3)
    others = [v for v in build.FMI_VERSIONS if v != version]
    assert not any(f"sources/fmi{v}_slave.c" in names for v in others)  # one API per binary
    assert not any(name.startswith("sources/fmi") and name.endswith(".h") for name in names)


def test_fmpy_validate_reports_no_problem(any_fmu):
    assert validate_fmu(str(any_fmu.path)) == []


def test_fmutool_check_reports_no_problem(any_fmu):
    """fmu-manipulation-toolbox checks either version against its XML schema and the standard's
    rules for causality, variability, initial and start values, units and model structure."""
    result = subprocess.run(
        [str(Path(sys.executable).with_name("fmutool")), "-input", str(any_fmu.path), "-check"],
        capture_output=True,
        text=True,
    )
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    assert f"compliant with FMI-{any_fmu.fmi_version}.0" in output
    assert "No semantic error" in output
    assert "ERROR" not in output.replace("logStatusError", "")


# How fmpy's simulate_fmu runs each version: FMI 3.0 also through its event mode.
SIMULATE = [(2, {}), (3, {}), (3, {"use_event_mode": True})]
SIMULATE_IDS = ["fmi2", "fmi3", "fmi3-event-mode"]


@pytest.mark.parametrize(("fmi_version", "options"), SIMULATE, ids=SIMULATE_IDS)
def test_simulates_in_fmpy_simulate_fmu(fmi_version, options):
    current = 2.0  # A: 1.48 N.m against 0.625 N.m of Coulomb friction
    result = simulate_fmu(
        str(build.build_fmu("drive2mass", fmi_version=fmi_version)),
        stop_time=0.5,
        step_size=62.5e-6,
        output_interval=0.01,
        start_values={"current_cmd": current},
        **options,
    )
    travel = plant_model("drive2mass").drive_facts()["travel_per_rad"]
    speed = result["load_speed"] / travel
    late = result["time"] >= 0.2
    slope = np.polyfit(result["time"][late], speed[late], 1)[0]
    assert slope == pytest.approx((0.74 * current - 0.625) / (2.9e-4 + 4.2e-4), rel=0.01)


@pytest.mark.parametrize(("fmi_version", "options"), SIMULATE, ids=SIMULATE_IDS)
def test_emps_simulates_in_fmpy_at_its_default_step(fmi_version, options):
    """simulate_fmu without a step size uses DefaultExperiment's (the 1 ms sample period); 3 V
    drives the axis to the speed where viscous friction takes the rest of the force."""
    result = simulate_fmu(
        str(build.build_fmu("emps", fmi_version=fmi_version)),
        stop_time=4.0,
        start_values={"current_cmd": 3.0},
        **options,
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


def test_sources_in_the_fmu_recompile(any_fmu, tmp_path):
    with zipfile.ZipFile(any_fmu.path) as archive:
        archive.extractall(tmp_path)
    sources = sorted((tmp_path / "sources").glob("*.c"))
    subprocess.run(
        [
            "gcc",
            *build.CFLAGS,
            f"-I{tmp_path / 'sources'}",
            f"-I{build.fmi_headers_dir(any_fmu.fmi_version)}",
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


def test_unknown_fmi_version_is_an_error():
    with pytest.raises(build.BuildError, match=r"FMI version 4 is not supported: expected one of"):
        build.build_fmu("emps", fmi_version=4)


@pytest.mark.parametrize("debug_logging", [True, False])
def test_events_reach_fmpys_logger_only_with_debug_logging(any_fmu, debug_logging):
    """fmpy instantiates with loggingOn = debug_logging and passes our logger callback; a push
    then a release of the axis logs its breakaway and its sticking only when logging is on (a
    model whose catalogue has no breakaway level, hsm150, gets a Coulomb friction)."""
    messages = []

    def logger(*arguments):
        """FMI 2.0: (environment, instance, status, category, message); FMI 3.0 without the
        instance."""
        category, message = arguments[-2:]
        messages.append((category.decode(), message.decode()))

    signal = np.array(
        [(0.0, 3.0), (0.02, 3.0), (0.02, 0.0), (0.4, 0.0)],
        dtype=[("time", float), ("current_cmd", float)],
    )
    simulate_fmu(
        str(any_fmu.path),
        stop_time=0.4,
        step_size=1e-4,
        input=signal,
        debug_logging=debug_logging,
        logger=logger,
        start_values={"coulomb_friction": 0.03} if any_fmu.model == "hsm150" else {},
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


def test_both_versions_are_kept_side_by_side(tmp_path, monkeypatch):
    """Keyed by fingerprint and version in the cache, by file name in an output folder; each
    version's build is found up to date on its own."""
    monkeypatch.setenv(build.CACHE_ENV, str(tmp_path / "cache"))
    fmi2, fmi3 = (build.build_fmu("emps", fmi_version=v) for v in (2, 3))
    assert (fmi2.name, fmi3.name) == ("emps.fmu", "emps-fmi3.fmu")
    assert build.fingerprint("emps", 2) != build.fingerprint("emps", 3)
    assert fmi3.parent.name == f"emps-{build.fingerprint('emps', 3)[:16]}" != fmi2.parent.name
    out = tmp_path / "out"
    built = [build.build_fmu("emps", out, fmi_version=v) for v in (2, 3)]
    stamps = [p.stat().st_mtime_ns for p in built]
    assert [p.name for p in sorted(out.iterdir())] == [
        "emps-fmi3.fmu",
        "emps-fmi3.fmu.sha256",
        "emps.fmu",
        "emps.fmu.sha256",
    ]
    again = [build.build_fmu("emps", out, fmi_version=v) for v in (2, 3)]
    assert [p.stat().st_mtime_ns for p in again] == stamps
    assert [read_model_description(str(p)).fmiVersion for p in built] == ["2.0", "3.0"]


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
