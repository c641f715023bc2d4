"""The sources/ folder of each FMU as an importer rebuilds it: with all warnings as errors at -O3,
through fmpy's own build, and without the project's -fvisibility=hidden: the binary then still
exports the fmi2 functions only, and two models loaded into one process stay apart."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

from fmu_build import build
from tests.fmu_build.conftest import MODELS

STRICT_FLAGS = (
    "-std=c99",
    "-O3",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-pedantic",
    "-fPIC",
    "-shared",
)  # no -fvisibility=hidden: what a user's own build would use


def rebuild_from_sources(fmu_path: Path, folder: Path) -> Path:
    """Extract the FMU into ``folder`` and compile ``sources/*.c`` with STRICT_FLAGS."""
    with zipfile.ZipFile(fmu_path) as archive:
        archive.extractall(folder)
    model = fmu_path.stem
    binary = folder / "binaries" / "linux64" / f"{model}.so"
    binary.unlink()
    result = subprocess.run(
        [
            "gcc",
            *STRICT_FLAGS,
            f"-I{folder / 'sources'}",
            f"-I{build.fmi_headers_dir()}",
            "-o",
            str(binary),
            *map(str, sorted((folder / "sources").glob("*.c"))),
            "-lm",
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr
    return binary


@pytest.fixture(scope="module")
def rebuilt(tmp_path_factory) -> dict[str, Path]:
    """Both FMUs extracted, their binaries rebuilt from sources/ with STRICT_FLAGS."""
    folders = {}
    for model in MODELS:
        folder = tmp_path_factory.mktemp(model)
        rebuild_from_sources(build.build_fmu(model), folder)
        folders[model] = folder
    return folders


def test_sources_build_with_warnings_as_errors_at_O3(rebuilt):
    for model, folder in rebuilt.items():
        assert (folder / "binaries" / "linux64" / f"{model}.so").stat().st_size > 0


def test_fmpy_compile_with_warnings_as_errors(model_fmu, tmp_path):
    fmu = tmp_path / model_fmu[1].name
    fmu.write_bytes(model_fmu[1].read_bytes())
    venv_bin = Path(sys.executable).parent
    # fmpy runs "cmake", which the venv provides (a dependency of fmpy): put it first on PATH
    env = {**os.environ, "PATH": os.pathsep.join([str(venv_bin), os.environ.get("PATH", "")])}
    result = subprocess.run(
        [str(venv_bin / "fmpy"), "compile", "--all-warnings", "--warning-as-error", str(fmu)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
    )
    assert result.returncode == 0, (result.stdout + result.stderr)[-4000:]
    assert f"binaries/linux64/{model_fmu[0]}.so" in zipfile.ZipFile(fmu).namelist()


def test_only_fmi2_functions_are_exported(rebuilt):
    for model, folder in rebuilt.items():
        binary = folder / "binaries" / "linux64" / f"{model}.so"
        result = subprocess.run(
            ["nm", "-D", "--defined-only", str(binary)], capture_output=True, text=True, check=True
        )
        names = [line.split()[-1] for line in result.stdout.splitlines() if line.strip()]
        assert "fmi2DoStep" in names
        assert [n for n in names if not n.startswith("fmi2")] == [], model


STEP_BOTH = textwrap.dedent(
    """
    import ctypes, json, sys
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    folders = json.loads(sys.argv[1])
    slaves, refs = {}, {}
    for model, folder in folders.items():
        # RTLD_GLOBAL: every exported symbol of one model is visible to the other
        ctypes.CDLL(f"{folder}/binaries/linux64/{model}.so", mode=ctypes.RTLD_GLOBAL)
    for model, folder in folders.items():
        description = read_model_description(folder)
        by_name = {v.name: v.valueReference for v in description.modelVariables}
        slave = FMU2Slave(guid=description.guid, unzipDirectory=folder,
                          modelIdentifier=model, instanceName=model)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slaves[model] = slave
        refs[model] = (by_name["current_cmd"], [by_name["motor_speed"], by_name["load_position"]])
    h = float(sys.argv[2])
    out = {model: [] for model in slaves}
    for k in range(300):
        for model, slave in slaves.items():
            if sys.argv[3] != "both" and model != sys.argv[3]:
                continue
            slave.setReal([refs[model][0]], [3.0])
            slave.doStep(k * h, h)
            out[model].append(slave.getReal(refs[model][1]))
    for slave in slaves.values():
        slave.terminate()
        slave.freeInstance()
    print(json.dumps(out))
    """
)


def test_two_models_in_one_process_stay_apart(rebuilt):
    def run(which: str) -> dict:
        result = subprocess.run(
            [
                sys.executable,
                "-c",
                STEP_BOTH,
                json.dumps({m: str(f) for m, f in rebuilt.items()}),
                "1e-4",
                which,
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert result.returncode == 0, result.stderr[-3000:]
        return json.loads(result.stdout)

    together = run("both")
    for model in MODELS:
        alone = run(model)[model]
        assert together[model] == alone
        assert alone[-1][0] > 0.0  # the axis moves under 3 A / 3 V
