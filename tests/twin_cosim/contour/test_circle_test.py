"""The circular test on the twin: Fine-Tune's reversal spikes, a gain mismatch's ellipse."""

from __future__ import annotations

import json
import textwrap

import pytest

from twin_cosim.contour.circle_test import MM_PER_MIN, CircleSpec, run_circle
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.scenario import load_machine

MISMATCH = """
axes:
  X:
    plant: {parameters: {backlash: 0.0, coulomb_friction: 0.0}}
    controller:
      parameters: {Kp_pos: 66.6667, Kp_vel: 0.2865, Ki_vel: 0.008, PP2: 0.0, PP3: 0.0082, f_H: 0.1}
      settings: {ff_velocity: 0.0, ff_acceleration: 0.0}
  Y:
    plant: {parameters: {backlash: 0.0, coulomb_friction: 0.0}}
    controller:
      parameters: {Kp_pos: 40.0, Kp_vel: 0.2865, Ki_vel: 0.008, PP2: 0.0, PP3: 0.0082, f_H: 0.1}
      settings: {ff_velocity: 0.0, ff_acceleration: 0.0}
"""


@pytest.fixture(scope="module")
def xy_table():
    machine = load_machine("xy_table")
    with MachinePlants(machine) as plants:
        yield machine, plants


def test_fine_tune_leaves_an_outward_spike_at_every_quadrant_transition(xy_table):
    machine, plants = xy_table
    for direction in ("ccw", "cw"):
        run = run_circle(machine, plants, CircleSpec(0.01, 1000 * MM_PER_MIN, direction))
        result = run.result
        assert result.speed_mm_min == pytest.approx(1000)
        assert [s.axis for s in result.spikes] == ["X", "Y", "X", "Y"]
        for spike in result.spikes:
            assert 5.0 < spike.height_um < 40.0
            assert 2.0 < spike.width_ms < 100.0
            after = ((spike.peak_deg - spike.angle_deg) * (1 if direction == "ccw" else -1)) % 360
            assert after < 20.0  # just after the transition, in the direction of travel
        assert result.G_um >= max(s.height_um for s in result.spikes)
        assert run.data.sum() * 250e-6 == pytest.approx(
            2 * 3.14159 * 0.01 / (1000 / 60e3), rel=1e-3
        )


@pytest.mark.parametrize("feed", [500.0, 2000.0])
def test_a_gain_mismatch_gives_an_ellipse_at_45_degrees_of_v_times_the_lag_difference(
    tmp_path, feed
):
    path = tmp_path / "mismatch.yaml"
    path.write_text(textwrap.dedent(MISMATCH))
    machine = load_machine(path)
    predicted = feed / 60e3 * (1 / 40.0 - 1 / 66.6667) * 1e6  # v |1/Kv_Y - 1/Kv_X|, um
    with MachinePlants(machine) as plants:
        for direction, major in (("ccw", 135.0), ("cw", 45.0)):
            spec = CircleSpec(0.01, feed * MM_PER_MIN, direction)
            result = run_circle(machine, plants, spec).result
            assert result.G_um == pytest.approx(predicted, rel=0.02)
            assert result.mismatch["size_um"] == pytest.approx(predicted, rel=0.02)
            assert result.mismatch["major_axis_deg"] == pytest.approx(major, abs=3.0)
            assert result.mismatch["lagging_axis"] == "Y"


def test_twin_circle_prints_g_f_h_and_the_spikes(twin_cli, tmp_path):
    done = twin_cli(
        "circle", "xy_table", "--radius", "5", "--feed", "2000", "--out", str(tmp_path), "--json"
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["G_um"] > 0 and summary["F_um"] > 0 and summary["H_um"] >= 0
    assert len(summary["spikes"]) == 8
    assert set(summary["spikes"][0]) >= {"angle_deg", "axis", "height_um", "width_ms"}
    assert (tmp_path / "circle.png").is_file()
    one = twin_cli(
        "circle", "xy_table", "--radius", "5", "--feed", "2000", "--direction", "cw",
        "--out", str(tmp_path / "cw"), "--json",
    )  # fmt: skip
    assert "H_um" not in json.loads(one.stdout)
    bad = twin_cli("circle", "reference1", "--radius", "5", "--feed", "500", "--out", str(tmp_path))
    assert bad.returncode == 2 and "axes" in bad.stderr and "Traceback" not in bad.stderr
