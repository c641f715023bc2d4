"""``twin circle``'s outputs: the feed reached, limits checked before a run, the ballbar's
figures in circle.json, the polar plot's scale; machine commands given a single-axis scenario."""

from __future__ import annotations

import json

import pytest

from twin_cosim.contour.circle_report import ring_division, signed


def test_a_capped_feed_is_said_in_the_headline_the_json_and_stderr(twin_cli, tmp_path):
    done = twin_cli(
        "circle", "xy_table", "--radius", "1", "--feed", "100000", "--direction", "ccw",
        "--out", str(tmp_path), "--no-plots",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "circle.json").read_text())
    reached = summary["feed_reached_mm_min"]
    assert 1000 < reached < 2000  # the jerk on a 1 mm radius caps it
    assert done.stdout.startswith(f"circle R 1 mm at {reached:.0f} mm/min (programmed 100000")
    assert "warning: ccw: feed" in done.stderr and "the jerk on radius 1 mm" in done.stderr
    assert summary["warnings"] and summary["feed_mm_min"] == 100000
    ballbar = summary["ballbar"]
    names = ("squareness_um_per_m", "scale_mismatch_um_per_m", "backlash_um", "lateral_play_um")
    names += ("centre_offset_um", "cyclic_error_um", "servo_mismatch_ms", "reversal_spikes_um")
    assert set(names) <= set(ballbar)
    assert set(ballbar["backlash_um"]["X"]) == {"positive", "negative"}


def test_a_circle_beyond_the_travel_is_refused_before_it_runs(twin_cli, tmp_path):
    out = tmp_path / "far"
    done = twin_cli("circle", "xy_table", "--radius", "5000", "--feed", "1000", "--out", str(out))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "circle of radius 5000 mm" in done.stderr and "axes.X.limits.travel" in done.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    "command",
    [
        ("circle", "reference1", "--radius", "5", "--feed", "500"),
        ("circle", "reference1"),
        ("ssp", "reference1"),
        ("simulate", "reference1", "--program", "scenarios/part.nc"),
    ],
)
def test_machine_commands_name_a_machine_scenario_for_a_single_axis_one(twin_cli, command):
    done = twin_cli(*command)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "needs a machine scenario" in done.stderr and "xy_table" in done.stderr
    assert "unknown key" not in done.stderr


def test_the_polar_plot_scale_is_a_round_division():
    assert ring_division(14.0) == 5.0  # 14 um in about 6 rings
    assert ring_division(0.9) == 0.2
    assert ring_division(160.0) == 50.0
    assert signed(-0.001) == "0.00" and signed(1.234) == "+1.23"
