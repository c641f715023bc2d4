"""The circular test: ISO 230-4 figures on known paths (a perfect circle, an offset one, an
ellipse, a bump), and on the twin: Fine-Tune's reversal spikes, a gain mismatch's ellipse."""

from __future__ import annotations

import json
import math
import textwrap

import numpy as np
import pytest

from twin_cosim.contour.circle import (
    MM_PER_MIN,
    CircleSpec,
    evaluate_circle,
    hysteresis,
    least_squares_circle,
    run_circle,
)
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import load_machine

R = 0.01


def _data(deviation=lambda a: 0.0 * a, centre=(0.0, 0.0), direction="ccw", n=7200):
    sign = 1.0 if direction == "ccw" else -1.0
    angle = math.radians(45) + sign * np.linspace(0, 2 * math.pi, n, endpoint=False)
    r = R + deviation(angle)
    t = np.arange(n) * 1e-3
    x = centre[0] + r * np.cos(angle)
    y = centre[1] + r * np.sin(angle)
    return RunRecord.from_columns({"t": t, "x": x, "y": y}, {"t": "s", "x": "m", "y": "m"})


def test_a_perfect_circle_has_no_deviation_and_no_spikes():
    result = evaluate_circle(_data(), R, "ccw", 0.0167)
    assert result.G_um < 1e-6 and result.F_um < 1e-6
    assert all(abs(s.height_um) < 1e-6 for s in result.spikes)
    assert [s.axis for s in result.spikes] == ["X", "Y", "X", "Y"]


def test_least_squares_circle_finds_an_offset_centre_and_g_ignores_it():
    data = _data(centre=(3e-6, -2e-6))
    assert least_squares_circle(data["x"], data["y"]) == pytest.approx((3e-6, -2e-6, R), abs=1e-12)
    result = evaluate_circle(data, R, "ccw", 0.0167)
    assert result.G_um < 1e-6  # G is about the least-squares centre
    assert result.F_um == pytest.approx(math.hypot(3, 2), rel=1e-3)  # F about the nominal one


def test_an_ellipse_at_45_degrees_is_the_servo_mismatch_signature():
    ellipse = evaluate_circle(_data(lambda a: 4e-6 * np.cos(2 * (a - math.pi / 4))), R, "ccw", 0.02)
    assert ellipse.G_um == pytest.approx(8.0, rel=1e-3)
    assert ellipse.mismatch["size_um"] == pytest.approx(8.0, rel=1e-3)
    assert ellipse.mismatch["major_axis_deg"] == pytest.approx(45.0, abs=0.1)
    assert ellipse.mismatch["lagging_axis"] == "X"  # CCW, major axis at 45 degrees


def test_a_bump_after_a_transition_is_its_spike_with_height_and_width():
    def bump(angle):  # 5 um outward, 10 degrees wide, 3 degrees after 90 (CCW)
        offset = np.degrees(angle) % 360 - 93.0
        return 5e-6 * np.exp(-0.5 * (offset / 2.0) ** 2)

    result = evaluate_circle(_data(bump), R, "ccw", 0.0167)
    spike = result.spikes[1]
    assert spike.axis == "Y" and spike.angle_deg == 90.0
    assert spike.height_um == pytest.approx(5.0, rel=0.05)
    assert spike.peak_deg == pytest.approx(93.0, abs=0.1)
    fwhm_deg = 2 * math.sqrt(2 * math.log(2)) * 2.0  # one sample per 0.05 degree and 1 ms
    assert spike.width_ms == pytest.approx(fwhm_deg / 0.05, rel=0.05)
    assert abs(result.spikes[0].height_um) < 0.1 * spike.height_um


def test_hysteresis_is_the_largest_radial_difference_of_the_two_directions():
    ccw = evaluate_circle(_data(lambda a: 2e-6 + 0 * a), R, "ccw", 0.02)
    cw = evaluate_circle(_data(lambda a: 1e-6 * np.sin(a), direction="cw"), R, "cw", 0.02)
    assert hysteresis(ccw, cw) == pytest.approx(3.0, rel=1e-3)


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
    bare = twin_cli(
        "circle", "xy_table", "--radius", "5", "--feed", "2000", "--direction", "cw",
        "--out", str(tmp_path / "bare"), "--json", "--no-plots",
    )  # fmt: skip
    assert json.loads(bare.stdout)["G_um"] == json.loads(one.stdout)["G_um"]
    assert (tmp_path / "bare" / "circle.json").is_file()
    assert not (tmp_path / "bare" / "circle.png").exists()
    bad = twin_cli("circle", "reference1", "--radius", "5", "--feed", "500", "--out", str(tmp_path))
    assert bad.returncode == 2 and "axes" in bad.stderr and "Traceback" not in bad.stderr
