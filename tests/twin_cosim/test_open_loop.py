"""Open-loop runs of the HSM150 bench: the .mat reader, the replay of a run's input torque by
the catalogue twin against physics, and the record with the measured speed beside the twin's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hsm150_data import HSM150_DATA, ROOT, needs_hsm150_data
from scipy.signal import lfilter

from twin_cosim.cli import main
from twin_cosim.measured import MeasuredRun, read_measured
from twin_cosim.open_loop import compare_open_loop, levels
from twin_cosim.run_record import RunRecord

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


def _simulate(tmp_path: Path, scenario: Path, run: Path, capsys) -> tuple[dict, pd.DataFrame]:
    """``twin simulate SCENARIO --machine RUN``: its JSON summary and its record."""
    out = tmp_path / "out"
    code = main(
        ["simulate", str(scenario), "--machine", str(run), "--data", str(HSM150_DATA)]
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
    return summary, record


@needs_hsm150_data
def test_simulate_replays_a_runs_input_torque_with_the_measured_speed_beside(tmp_path, capsys):
    """The catalogue rotor driven by 0.05 then 0.06 N.m from rest: w(t) = tau / B (1 - e^(-t/T)),
    T = J / B, each level from where the previous left; the record holds the twin's speed and
    the measured one."""
    shipped = (ROOT / "scenarios" / "hsm150.yaml").read_text()
    assert "  drive: measured_torque\n" in shipped
    scenario = tmp_path / "hsm150_input.yaml"
    scenario.write_text(shipped.replace("  drive: measured_torque\n", "  drive: input_torque\n"))
    run = HSM150_DATA / "idf_pos_0.06_2.mat"
    summary, record = _simulate(tmp_path, scenario, run, capsys)
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
    assert [round(level["commanded"], 3) for level in steady] == [0.05, 0.06]
    assert steady[1]["twin_rad_s"] == pytest.approx(852.0, abs=3.0)  # 0.06 / B, nearly
    assert 200.0 < steady[1]["measured_rad_s"] < 250.0  # the real motor: far slower


@needs_hsm150_data
def test_the_shipped_scenario_drives_the_rotor_by_the_measured_torque(tmp_path, capsys):
    """The rotor's input is the current the bench measured: each 1 ms sample's torque held,
    J dw/dt = tau_k - B w solved exactly over the sample, w_k+1 = a w_k + (1 - a) tau_k / B with
    a = e^(-B dt / J); the levels are those of the input torque."""
    run = HSM150_DATA / "idf_neg_0.04_2.mat"
    summary, record = _simulate(tmp_path, ROOT / "scenarios" / "hsm150.yaml", run, capsys)
    assert summary["open_loop"]["drive"] == "measured_torque"
    torque = read_measured(run).record["measured_torque"]  # N.m, a new value every sample
    np.testing.assert_allclose(record["current"], torque / KT, atol=1e-9)
    a = np.exp(-B * 1e-3 / J)
    exact = lfilter([0.0, 1.0 - a], [1.0, -a], torque / B)  # w at each sample, from rest
    assert np.max(np.abs(record["motor_speed"].to_numpy() - exact)[100:]) < 2.0  # rad/s
    steady = summary["open_loop"]["levels"]
    assert [round(level["commanded"], 3) for level in steady] == [-0.03, -0.04]


def test_a_run_driven_by_its_measured_torque_keeps_the_levels_it_was_commanded():
    """Driven by a noisy measured torque, the run's levels and steady speeds are those of its
    input torque; the levels' unit is the input torque's."""
    t = np.arange(2000) * 1e-3
    input_torque = np.where(t < 1.0, 0.05, 0.06)  # N.m
    measured_torque = input_torque + np.random.default_rng(0).normal(0.0, 0.02, t.size)
    speed = np.where(t < 1.0, 100.0, 150.0)  # rad/s
    signals = {
        "t": t,
        "motor_angle": np.cumsum(speed) * 1e-3,
        "motor_speed": speed,
        "input_torque": input_torque,
        "measured_torque": measured_torque,
    }
    run = MeasuredRun.from_signals("bench.mat", signals).open_loop("measured_torque", 1e-3)
    assert run.experiment_signal == "input_torque"
    record = RunRecord.from_columns({"t": t, "x": run.x, "motor_speed": 1.1 * speed})
    found = compare_open_loop(run, record, 1e-3)
    assert found.drive == "measured_torque"
    assert [(lv.start_s, lv.commanded) for lv in found.levels] == [(0.0, 0.05), (1.0, 0.06)]
    assert found.commanded_unit == "N.m"
    assert [lv.relative_error_pct for lv in found.levels] == pytest.approx([10.0, 10.0])


def test_an_open_loop_run_without_a_commanded_input_takes_its_levels_from_its_drive():
    t = np.arange(100) * 1e-3
    current = np.where(t < 0.05, 1.0, 1.2)  # A
    signals = {"t": t, "motor_angle": t, "motor_speed": np.ones(t.size), "current": current}
    run = MeasuredRun.from_signals("bench.csv", signals).open_loop("current", 1e-3)
    assert run.experiment_signal == "current"
    np.testing.assert_array_equal(run.experiment_input, current)
    closed = MeasuredRun.from_signals("axis.csv", {"t": t, "x_ref": t, "x": t, "current": current})
    assert closed.experiment_signal is None and closed.experiment_input is None
