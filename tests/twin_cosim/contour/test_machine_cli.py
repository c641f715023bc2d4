"""The machine branches of the command line: options for one axis refused, twin ssp."""

from __future__ import annotations

import zipfile


def test_single_axis_options_are_refused_for_a_machine(twin_cli, tmp_path):
    done = twin_cli(
        "optimize", "xy_table", "--method", "ce", "--tolerance", "0.1", "--out", str(tmp_path)
    )
    assert done.returncode == 2 and "--tolerance" in done.stderr
    done = twin_cli("optimize", "reference1", "--method", "ce", "--target", "G")
    assert done.returncode == 2 and "machine scenario" in done.stderr
    done = twin_cli("circle", "xy_table", "--radius", "5")
    assert done.returncode == 2 and "--feed" in done.stderr
    assert "Traceback" not in done.stderr


def test_twin_ssp_writes_a_package(twin_cli, tmp_path):
    done = twin_cli("ssp", "xy_table", "--out", str(tmp_path / "xy.ssp"))
    assert done.returncode == 0, done.stderr
    with zipfile.ZipFile(tmp_path / "xy.ssp") as archive:
        assert "SystemStructure.ssd" in archive.namelist()
