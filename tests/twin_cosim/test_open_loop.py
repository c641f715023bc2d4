"""Open-loop runs of the HSM150 bench: the .mat reader, the replay of a run's input torque by
the catalogue twin against physics, and the record with the measured speed beside the twin's."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hsm150_data import HSM150_DATA, ROOT, needs_hsm150_data

from twin_cosim.cli import main
from twin_cosim.measured import read_measured
from twin_cosim.open_loop import levels

J, B, KT = 1.2e-4, 7.03e-5, 0.0458  # the catalogue: kg.m2, N.m.s/rad, N.m/A


def test_levels_are_the_stretches_of_one_drive_value():
    t = np.arange(100) * 1e-3
    drive = np.concatenate([np.full(40, 0.05), np.full(5, 0.055), np.full(55, 0.06)])
    assert levels(t, drive) == [(0, 40), (45, 100)]  # 5 samples: a transition


@needs_hsm150_data
def test_an_hsm150_run_reads_with_its_columns_and_scalars():
    run = read_measured(HSM150_DATA / "idf_pos_0.06_1.mat")
    assert run.period == pytest.approx(1e-3)
    assert len(run.t) == 20000
    torque = run.record["input_torque"]
    assert set(np.round(np.unique(torque), 6)) == {0.05, 0.06}
    assert run.record.units["motor_speed"] == "rad/s"
    assert run.scalars["J"] == pytest.approx(1.2e-4)
    assert run.scalars["B"] == pytest.approx(7.03e-5)


@needs_hsm150_data
def test_simulate_replays_a_runs_input_torque_with_the_measured_speed_beside(tmp_path, capsys):
    """The catalogue rotor driven by 0.05 then 0.06 N.m from rest: w(t) = tau / B (1 - e^(-t/T)),
    T = J / B, each level from where the previous left; the record holds the twin's speed and
    the measured one."""
    out = tmp_path / "out"
    run = HSM150_DATA / "idf_pos_0.06_2.mat"
    code = main(
        ["simulate", str(ROOT / "scenarios" / "hsm150.yaml"), "--machine", str(run)]
        + ["--out", str(out), "--json", "--no-plots"]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    record = pd.read_csv(out / "record.csv")
    assert {"motor_speed", "measured_motor_speed", "x", "measured_x"} <= set(record.columns)
    measured = read_measured(run)
    np.testing.assert_allclose(
        record["measured_motor_speed"], measured.record["motor_speed"], atol=1e-12
    )
    t = record["t"].to_numpy()
    tau = np.where(t < 10.0, 0.05, 0.06)
    at_step = 0.05 / B * (1 - np.exp(-10.0 * B / J))
    analytic = np.where(
        t < 10.0,
        0.05 / B * (1 - np.exp(-t * B / J)),
        tau / B + (at_step - tau / B) * np.exp(-(t - 10.0) * B / J),
    )
    # the drive's speed: the encoder's difference over each 1 ms step, one step behind
    assert np.max(np.abs(record["motor_speed"] - analytic)[100:]) < 2.0  # rad/s
    steady = summary["open_loop"]["levels"]
    assert [round(level["drive"], 3) for level in steady] == [0.05, 0.06]
    assert steady[1]["twin_rad_s"] == pytest.approx(852.0, abs=3.0)  # 0.06 / B, nearly
    assert 200.0 < steady[1]["measured_rad_s"] < 250.0  # the real motor: far slower
