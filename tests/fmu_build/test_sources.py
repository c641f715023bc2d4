"""The sources/ folder of each FMU of each FMI version as an importer rebuilds it: with all warnings
as errors at -O3, through fmpy's own build, and without the project's -fvisibility=hidden: the
binary then still exports the functions of its FMI version only, and two models loaded into one
process stay apart."""

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
from tests.fmu_build.conftest import MODELS, BuiltFmu

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


def rebuild_from_sources(fmu: BuiltFmu, folder: Path) -> Path:
    """Extract the FMU into ``folder`` and compile ``sources/*.c`` with STRICT_FLAGS."""
    with zipfile.ZipFile(fmu.path) as archive:
        archive.extractall(folder)
    binary = folder / build.binary_path(fmu.model, fmu.fmi_version)
    binary.unlink()
    result = subprocess.run(
        [
            "gcc",
            *STRICT_FLAGS,
            f"-I{folder / 'sources'}",
            f"-I{build.fmi_headers_dir(fmu.fmi_version)}",
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


@pytest.fixture(scope="module", params=build.FMI_VERSIONS, ids=lambda v: f"fmi{v}")
def rebuilt(request, tmp_path_factory) -> tuple[int, dict[str, Path]]:
    """An FMI version and both models' FMUs of it extracted, their binaries rebuilt from
    sources/ with STRICT_FLAGS."""
    version, folders = request.param, {}
    for model in MODELS:
        folder = tmp_path_factory.mktemp(f"{model}-fmi{version}")
        fmu = BuiltFmu(model, version, build.build_fmu(model, fmi_version=version))
        rebuild_from_sources(fmu, folder)
        folders[model] = folder
    return version, folders


def test_sources_build_with_warnings_as_errors_at_O3(rebuilt):
    version, folders = rebuilt
    for model, folder in folders.items():
        assert (folder / build.binary_path(model, version)).stat().st_size > 0


def test_fmpy_compile_with_warnings_as_errors(any_fmu, tmp_path):
    """fmpy builds FMI 2.0 from SourceFiles of modelDescription.xml, FMI 3.0 from
    sources/buildDescription.xml."""
    fmu = tmp_path / any_fmu.path.name
    fmu.write_bytes(any_fmu.path.read_bytes())
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
    binary = build.binary_path(any_fmu.model, any_fmu.fmi_version)
    assert binary in zipfile.ZipFile(fmu).namelist()


def test_only_the_functions_of_the_fmi_version_are_exported(rebuilt):
    version, folders = rebuilt
    for model, folder in folders.items():
        binary = folder / build.binary_path(model, version)
        result = subprocess.run(
            ["nm", "-D", "--defined-only", str(binary)], capture_output=True, text=True, check=True
        )
        names = [line.split()[-1] for line in result.stdout.splitlines() if line.strip()]
        assert f"fmi{version}DoStep" in names
        assert [n for n in names if not n.startswith(f"fmi{version}")] == [], model


STEP_BOTH = textwrap.dedent(
    """
    import ctypes, json, sys
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    folders, version = json.loads(sys.argv[1]), int(sys.argv[4])
    platform = {2: "linux64", 3: "x86_64-linux"}[version]
    slaves, refs = {}, {}
    for model, folder in folders.items():
        # RTLD_GLOBAL: every exported symbol of one model is visible to the other
        ctypes.CDLL(f"{folder}/binaries/{platform}/{model}.so", mode=ctypes.RTLD_GLOBAL)
    for model, folder in folders.items():
        description = read_model_description(folder)
        by_name = {v.name: v.valueReference for v in description.modelVariables}
        slave = (FMU2Slave if version == 2 else FMU3Slave)(
            guid=description.guid, unzipDirectory=folder, modelIdentifier=model,
            instanceName=model)
        slave.instantiate()
        if version == 2:
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
            (slave.setReal if version == 2 else slave.setFloat64)([refs[model][0]], [3.0])
            slave.doStep(k * h, h)
            out[model].append((slave.getReal if version == 2 else slave.getFloat64)(refs[model][1]))
    for slave in slaves.values():
        slave.terminate()
        slave.freeInstance()
    print(json.dumps(out))
    """
)


def test_two_models_in_one_process_stay_apart(rebuilt):
    version, folders = rebuilt

    def run(which: str) -> dict:
        result = subprocess.run(
            [
                sys.executable,
                "-c",
                STEP_BOTH,
                json.dumps({m: str(f) for m, f in folders.items()}),
                "1e-4",
                which,
                str(version),
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
