"""Figures from residuals: the benchmark's relative errors and the response to pulses."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.data.residuals import anchored, pulse_response, relative_errors
from twin_cosim.measured import MeasuredRun
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord

DT = 1e-3


def run_and_record(ringing: bool):
    t = np.arange(6000) * DT
    x_sim = 0.1 * (1 - np.cos(2 * np.pi * 0.2 * t))
    pulses = np.where((t % 1.0 >= 0.5) & (t % 1.0 < 0.65), 1.0, 0.0)
    x = x_sim.copy()
    if ringing:  # a flexibility excited by every pulse edge rings at 30 Hz for a few periods
        for edge in t[1:][np.abs(np.diff(pulses)) > 0.5]:
            after = t >= edge
            tau = t[after] - edge
            x[after] += 2e-6 * np.exp(-tau / 0.03) * np.sin(2 * np.pi * 30.0 * tau)
    run = MeasuredRun.from_signals(
        "run.mat", {"t": t, "x_ref": x_sim, "x": x, "current": np.sin(t)}
    )
    record = RunRecord.from_columns({"t": t, "x": x_sim, "current": np.sin(t)})
    grid = ReferenceGrid(DT, x_sim, np.gradient(x_sim, DT), np.zeros_like(t))
    return run, record, pulses, grid


def test_a_flexibility_rings_after_the_pulse_edges():
    run, record, pulses, grid = run_and_record(ringing=True)
    response = pulse_response(run, record, pulses, grid)
    assert response["edges"] == 12
    assert response["energy_share"] > 0.9 and response["enrichment"] > 2.0
    # the acceleration of a damped ringing peaks a little above its frequency
    assert response["ringing_hz"] == pytest.approx(30.0, rel=0.15)


def test_relative_errors_follow_the_benchmark_formula():
    run, record, _, _ = run_and_record(ringing=True)
    errors = relative_errors(run, record)
    expected = 100 * np.linalg.norm(run.x - record["x"]) / np.linalg.norm(run.x)
    assert errors["position"] == pytest.approx(expected)
    assert errors["force"] == 0.0
    assert errors["acceleration"] > errors["velocity"] > errors["position"]
    assert relative_errors(*run_and_record(ringing=False)[:2]) == {
        "position": 0.0,
        "velocity": 0.0,
        "acceleration": 0.0,
        "force": 0.0,
    }


def test_an_anchored_residual_counts_from_each_start():
    residual = np.array([1.0, 2.0, 3.0, 10.0, 12.0, 15.0, 4.0])
    found = anchored(residual, np.array([1, 3, 6]))
    np.testing.assert_array_equal(found, [1.0, 0.0, 1.0, 0.0, 2.0, 5.0, 0.0])


def test_an_open_loop_run_has_velocity_errors_and_no_force():
    """An open-loop run's command is its measured drive signal, the twin's alike: no force
    error; its velocity error is the benchmark's formula on the position's derivative."""
    t = np.arange(4000) * 1e-3
    x = 1e-3 * (t - 1.7 * (1 - np.exp(-t / 1.7)))
    signals = {"t": t, "motor_angle": x / 1e-3, "motor_speed": np.gradient(x / 1e-3, t)}
    signals["input_torque"] = np.full(t.size, 0.05)
    run = MeasuredRun.from_signals("bench.mat", signals).open_loop("input_torque", 1e-3)
    record = RunRecord.from_columns({"t": t, "x": 0.9 * x, "current": np.full(t.size, 1.0)})
    errors = relative_errors(run, record)
    assert "force" not in errors
    assert errors["velocity"] == pytest.approx(10.0, rel=1e-3)  # the twin 10 % slow throughout
    assert errors["position"] == pytest.approx(10.0, rel=1e-9)
