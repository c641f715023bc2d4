"""Kv from constant-speed runs: the position loop's gain, as the following error v / Kp_pos
gives it with the velocity feedforward off; nearly none with it on."""

from __future__ import annotations

import dataclasses
import json

import pytest

from twin_cosim.controller_set import TABLE3
from twin_cosim.scenario import load_scenario
from twin_cosim.servo.following import following_test


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
