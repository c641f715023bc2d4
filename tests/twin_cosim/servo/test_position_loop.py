"""The step test: its figures against a textbook step response and an independent computation
from the record; the twin's step against the linearised closed position loop.

Kv from constant-speed runs: the position loop's gain, as the following error v / Kp_pos
gives it with the velocity feedforward off; nearly none with it on.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest

from twin_cosim.controller_set import TABLE3
from twin_cosim.frequency.linear import LinearLoops, TwoMass, closed
from twin_cosim.plant_model import plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import load_scenario
from twin_cosim.servo.position_loop import following_test, step_figures, step_test


def second_order_step(zeta: float, f_n: float, size: float) -> RunRecord:
    """x(t) of a second-order system's step of ``size`` (m), sampled at 250 us."""
    t = np.arange(4000) * 250e-6
    w_n = 2 * math.pi * f_n
    w_d = w_n * math.sqrt(1 - zeta**2)
    x = size * (
        1
        - np.exp(-zeta * w_n * t)
        * (np.cos(w_d * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(w_d * t))
    )
    return RunRecord.from_columns({"t": t, "x": x, "current": np.zeros(len(t))})


@pytest.mark.parametrize("size", [1e-4, -2e-5])
def test_figures_of_a_second_order_step_are_the_textbook_ones(size):
    zeta, f_n = 0.3, 20.0
    record = second_order_step(zeta, f_n, size)
    f = step_figures(record, 0.0, size, band_um=0.01 * abs(size) * 1e6)
    overshoot = math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    assert f.overshoot_pct == pytest.approx(100 * overshoot, rel=1e-3)
    assert f.overshoot_um == pytest.approx(overshoot * abs(size) * 1e6, rel=1e-3)
    w_d = 2 * math.pi * f_n * math.sqrt(1 - zeta**2)
    assert f.peak_time_ms == pytest.approx(math.pi / w_d * 1e3, abs=0.25)
    # settled to 1 %: the envelope exp(-zeta w_n t) / sqrt(1 - zeta^2) bounds it from above
    envelope = -math.log(0.01 * math.sqrt(1 - zeta**2)) / (zeta * 2 * math.pi * f_n) * 1e3
    assert 0.7 * envelope < f.settling_time_ms <= envelope + 0.25
    assert f.rise_time_ms > 0 and f.final_error_um < 1e-3


def independent_figures(frame: pd.DataFrame, band_um: float) -> tuple[float, float]:
    """Overshoot (%) and settling time (ms) computed again from step.csv by a plain reading of
    their definitions: the setpoint's step and the last sample outside the band."""
    target = frame["setpoint"].iloc[0]
    start = frame["x"].iloc[0]
    size = target - start
    overshoot = max(0.0, (frame["x"] - start).max() / size - 1.0) * 100
    outside = np.flatnonzero(np.abs(frame["x"] - target) * 1e6 > band_um)
    return overshoot, frame["t"].iloc[outside[-1] + 1] * 1e3


def test_the_twin_step_without_nonlinearities_is_the_linearised_closed_loops_step(plant):
    """The twin's record against the linearised cascade (held plant, PI, lifted position loop)
    stepped by the same size: the same response."""
    scenario = load_scenario("reference1")
    linear = plant_model("drive2mass").nonlinear_off
    scenario = dataclasses.replace(
        scenario, plant_parameters={**scenario.plant_parameters, **linear}
    )
    size = 5e-5
    result = step_test(plant, scenario, size, 0.2)
    loop = closed(
        LinearLoops(
            TwoMass.of_plant("drive2mass"), scenario.tuned, scenario.settings
        ).position_open()
    )
    state = np.zeros(loop.a.shape[0])
    expected = []
    for _ in range(len(result.record["t"])):
        expected.append((loop.c @ state)[0])
        state = loop.a @ state + loop.b[:, 0] * size
    moved = np.asarray(result.record["x"]) - float(scenario.reference.position[0])
    np.testing.assert_allclose(moved, expected, atol=1e-11)


def test_step_command_writes_figures_an_independent_reading_of_its_record_confirms(
    twin_cli, tmp_path
):
    """Goal: overshoot and settling time within 5 % of an independent computation from the
    record. A position gain of 140 1/s overshoots, then the load sticks outside the band until
    the integral breaks it away: a long tail."""
    stiff = tmp_path / "stiff.yaml"
    stiff.write_text(
        "{Kp_pos: 140.0, Kp_vel: 0.2865, Ki_vel: 0.008, PP2: 0.7, PP3: 0.008, f_H: 0.1}"
    )
    result = twin_cli(
        "step", "reference1", "--size", "0.05", "--band", "0.5", "--params", str(stiff),
        "--out", str(tmp_path), "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    frame = pd.read_csv(tmp_path / "step.csv")
    overshoot, settling = independent_figures(frame, 0.5)
    assert summary["settling_time_ms"] == pytest.approx(settling, rel=0.05)
    assert summary["overshoot_pct"] == pytest.approx(overshoot, rel=0.05)
    assert overshoot > 5.0 and summary["tail_ms"] > 100.0
    for name in ("step.txt", "step.png", "step.json"):
        assert (tmp_path / name).is_file()
    assert "settling time to +-0.5 um" in (tmp_path / "step.txt").read_text()
    refused = twin_cli("step", "reference1", "--size", "0", "--out", str(tmp_path))
    assert refused.returncode == 2 and "--size" in refused.stderr
    assert "Traceback" not in refused.stderr


@pytest.mark.parametrize("name", ["ft", "ga"])
def test_kv_is_the_position_gain(plant, name):
    """Goal: Kv within 2 % of Kp_pos (the speed loop's integrator leaves no droop)."""
    scenario = dataclasses.replace(load_scenario("reference1"), tuned=TABLE3[name])
    result = following_test(plant, scenario, [0.005, 0.02], dwell_s=0.25)
    assert result.kv_per_s == pytest.approx(TABLE3[name].Kp_pos, rel=0.02)
    for level in result.levels:
        assert level.error_um == pytest.approx(
            level.speed_m_s / TABLE3[name].Kp_pos * 1e6, rel=0.02
        )
        assert abs(level.error_with_feedforward_um) < 1e-3 * abs(level.error_um)


def test_half_a_feedforward_halves_the_following_error(plant):
    scenario = load_scenario("reference1")
    half = dataclasses.replace(
        scenario, settings=dataclasses.replace(scenario.settings, ff_velocity=0.5)
    )
    result = following_test(plant, half, [0.01], dwell_s=0.25)
    for level in result.levels:
        assert level.error_with_feedforward_um == pytest.approx(0.5 * level.error_um, rel=0.02)


def test_kv_command_files(twin_cli, tmp_path):
    result = twin_cli(
        "kv", "reference1", "--speeds", "0.01", "0.02", "--dwell", "0.2", "--out", str(tmp_path),
        "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["kv_over_position_gain"] == pytest.approx(1.0, abs=0.02)
    assert summary["kv_m_min_per_mm"] == pytest.approx(summary["kv_per_s"] * 0.06)
    assert len(summary["levels"]) == 4
    for name in ("kv.txt", "kv.png", "kv.json"):
        assert (tmp_path / name).is_file()
