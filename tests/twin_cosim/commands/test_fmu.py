"""``twin build --fmi``: the FMI version of the FMU it builds."""

from __future__ import annotations

from pathlib import Path

from fmpy import read_model_description


def test_build_fmi3_writes_the_fmi3_fmu_beside_the_fmi2_one(tmp_path, twin_cli):
    for option, name, version in (
        ([], "emps.fmu", "2.0"),
        (["--fmi", "3"], "emps-fmi3.fmu", "3.0"),
    ):
        result = twin_cli("build", "emps", "--out", str(tmp_path), *option)
        assert result.returncode == 0, result.stderr
        fmu = Path(result.stdout.splitlines()[0])
        assert fmu == tmp_path / name
        assert read_model_description(str(fmu)).fmiVersion == version
    assert sorted(p.name for p in tmp_path.glob("*.fmu")) == ["emps-fmi3.fmu", "emps.fmu"]


def test_an_unknown_fmi_version_is_refused_by_the_parser(twin_cli):
    result = twin_cli("build", "--fmi", "4")
    assert result.returncode == 2
    assert "argument --fmi: invalid choice: 4 (choose from 2, 3)" in result.stderr
