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


def test_no_label_of_the_polar_plot_lies_on_another(tmp_path, saved_figure):
    """Spikes at every transition in both directions (where the labels used to overprint at 90
    and 270 degrees and on the 0 degree tick): every text drawn stands clear of every other."""
    import math

    import numpy as np

    from twin_cosim.contour.ballbar import ballbar_figures
    from twin_cosim.contour.circle import evaluate_circle
    from twin_cosim.contour.circle_report import ballbar_table, plot_circle
    from twin_cosim.run_record import RunRecord

    radius, n = 0.01, 7200
    results = []
    for direction, sign in (("cw", -1.0), ("ccw", 1.0)):
        angle = math.radians(45) + sign * np.linspace(0, 2 * math.pi, n, endpoint=False)
        travelled = np.degrees(sign * angle)
        r = radius + sum(
            14e-6 * np.exp(-0.5 * (((travelled - sign * at) % 360 - 3.0) / 2.0) ** 2)
            for at in (0.0, 90.0, 180.0, 270.0)
        )
        data = RunRecord.from_columns(
            {"t": np.arange(n) * 1e-3, "x": r * np.cos(angle), "y": r * np.sin(angle)},
            {"t": "s", "x": "m", "y": "m"},
        )
        results.append((direction.upper(), evaluate_circle(data, radius, direction, 0.0167)))
    assert all(len(result.spikes) == 4 for _, result in results)
    figures = ballbar_figures([result for _, result in results], radius, {"X": 0.01, "Y": 0.01})
    plot_circle(
        results, 10.0, "twin circle xy_table", tmp_path / "c.png", ballbar_table({"": figures})
    )
    fig = saved_figure["fig"]
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.table import Table
    from matplotlib.text import Text

    renderer = FigureCanvasAgg(fig).get_renderer()
    texts = fig.findobj(lambda a: isinstance(a, Text) and a.get_visible())
    texts += [c.get_text() for t in fig.findobj(Table) for c in t.get_celld().values()]
    boxes = [text.get_window_extent(renderer) for text in texts if text.get_text().strip()]
    assert len(boxes) > 20  # the angles, the scale, the title, the table's cells
    for k, box in enumerate(boxes):
        for other in boxes[k + 1 :]:
            assert not box.overlaps(other), (box, other)
