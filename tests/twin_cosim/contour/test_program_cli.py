"""``twin simulate MACHINE --program PART.nc``: contour metrics beside the axes', refusals."""

from __future__ import annotations

import json

PART = """(a rounded corner and back)
G17 G21 G90
G01 X4 F1200
G03 X6 Y2 R2
G01 Y4
G04 P0.05
G00 X0 Y0
M30
"""


def test_simulate_a_program_prints_contour_and_axis_metrics(twin_cli, tmp_path):
    program = tmp_path / "part.nc"
    program.write_text(PART)
    done = twin_cli(
        "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / "o"), "--json"
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert 0 < summary["contour_error_rms_um"] < summary["contour_error_max_um"] < 100
    assert set(summary["axes"]) == {"X", "Y"}
    assert summary["axes"]["Y"]["E_pk_um"] > 0
    assert (tmp_path / "o" / "contour.png").is_file()
    assert (tmp_path / "o" / "X.csv").is_file()
    bare = twin_cli(
        "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / "b"),
        "--json", "--no-plots",
    )  # fmt: skip
    assert json.loads(bare.stdout)["contour_error_max_um"] == summary["contour_error_max_um"]
    assert not (tmp_path / "b" / "contour.png").exists()
    assert (tmp_path / "b" / "summary.json").is_file()


def test_a_line_outside_the_subset_exits_2_naming_line_and_word(twin_cli, tmp_path):
    program = tmp_path / "bad.nc"
    program.write_text("G21 G90\nG01 X1 F100\nG01 X2 A4\n")
    done = twin_cli("simulate", "xy_table", "--program", str(program), "--out", str(tmp_path))
    assert done.returncode == 2
    assert "line 3" in done.stderr and "A4" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "contour.csv").exists()  # nothing ran


def test_a_program_needs_a_machine_scenario(twin_cli, tmp_path):
    program = tmp_path / "part.nc"
    program.write_text(PART)
    done = twin_cli("simulate", "reference1", "--program", str(program), "--out", str(tmp_path))
    assert done.returncode == 2
    assert "axes" in done.stderr


def test_an_axis_leaving_the_band_exits_1_with_a_warning(twin_cli, tmp_path):
    machine = tmp_path / "narrow.yaml"
    machine.write_text("axes: {X: {}, Y: {}}\noptimize: {abort_error_um: 1.0}\n")
    program = tmp_path / "part.nc"
    program.write_text(PART)
    done = twin_cli("simulate", str(machine), "--program", str(program), "--out", str(tmp_path))
    assert done.returncode == 1
    assert "axis X: the loop diverged" in done.stderr
