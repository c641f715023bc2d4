"""1,000 instantiate / initialise / step / reset / free cycles under valgrind memcheck, through
either FMI version's API: no leak."""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from fmu_build.build import FMI_VERSIONS, binary_path, build_fmu, fmi_headers_dir

HERE = Path(__file__).parent


@pytest.mark.slow
@pytest.mark.parametrize("fmi_version", FMI_VERSIONS)
@pytest.mark.parametrize("model", ["drive2mass", "emps"])
def test_no_leak_over_1000_cycles(model, fmi_version, tmp_path):
    if shutil.which("valgrind") is None:
        pytest.fail("valgrind is not installed (.ci/run installs it with apt-get)")
    fmu_path = build_fmu(model, fmi_version=fmi_version)
    with zipfile.ZipFile(fmu_path) as archive:
        archive.extract(binary_path(model, fmi_version), tmp_path)
    binary = tmp_path / binary_path(model, fmi_version)
    driver = tmp_path / "leak_check"
    subprocess.run(
        [
            "gcc",
            "-std=c99",
            "-Wall",
            "-Werror",
            f"-DFMI_VERSION={fmi_version}",
            f"-I{fmi_headers_dir(fmi_version)}",
            "-o",
            str(driver),
            str(HERE / "leak_check.c"),
            "-ldl",
        ],
        check=True,
    )
    guid = read_model_description(str(fmu_path)).guid
    result = subprocess.run(
        [
            "valgrind",
            "--leak-check=full",
            "--errors-for-leak-kinds=definite,indirect,possible",
            "--error-exitcode=99",
            str(driver),
            str(binary),
            guid,
            "1000",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-3000:]
    assert "ERROR SUMMARY: 0 errors" in result.stderr
    assert "All heap blocks were freed -- no leaks are possible" in result.stderr
    allocations = int(
        re.search(r"total heap usage: ([\d,]+) allocs", result.stderr).group(1).replace(",", "")
    )
    assert allocations >= 2 * 1000  # instance and its name, every cycle: the cycles really ran
