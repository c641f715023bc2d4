"""The data a diagnosis works on: runs without the motion it needs are refused, outliers are
repaired and reported (or the run refused), the encoder's grid is read off a position."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scenario_texts import scenario_text

from twin_cosim.gap.data.context import (
    build_context,
    estimate_resolution,
    missing_regimes,
    repeat_groups,
    screen_outliers,
)
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.synth import synthesize
from twin_cosim.measured import MeasuredDataError, MeasuredRun, read_measured_csv
from twin_cosim.scenario import load_scenario


def _run(tmp_path: Path, text: str, name: str):
    """A scenario file of ``text`` and a synthetic run of it (no effect, seeded noise)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    scenario = load_scenario(path)
    run = tmp_path / f"{name}.csv"
    synthesize(scenario, [], seed=3).run.frame().to_csv(run, index=False)
    return scenario, read_measured_csv(run)


def test_a_run_without_a_reversal_is_refused_naming_the_file(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(back=False, repeat=2), "oneway")
    with pytest.raises(MeasuredDataError) as error:
        build_context(scenario, [run], [], None, DiagnosisSettings())
    message = str(error.value)
    assert "oneway.csv (t = 0 to " in message
    assert "training data (time split at t = " in message
    assert "hold no reversal" in message
    assert "motion" not in message.split("hold no")[1].split(";")[0]


def test_a_training_half_that_only_dwells_is_refused(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(dwell=1.5, repeat=1), "dwell")
    with pytest.raises(
        MeasuredDataError,
        match=r"dwell\.csv .*the training data .* hold no "
        r"motion and no reversal",
    ):
        build_context(scenario, [run], [], None, DiagnosisSettings(split=0.3))


def test_held_out_data_are_checked_too(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(dwell=1.5, repeat=1), "late")
    with pytest.raises(MeasuredDataError, match=r"the held-out data .* hold no .*reversal"):
        build_context(scenario, [run], [], None, DiagnosisSettings(split=0.9))


def test_a_run_that_moves_and_reverses_in_both_parts_passes(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(repeat=2), "both")
    context = build_context(scenario, [run], [], None, DiagnosisSettings())
    grids = [scenario.reference]
    assert missing_regimes(context.train, grids) == []
    assert missing_regimes(context.judged, grids) == []


def run_with(current: np.ndarray) -> MeasuredRun:
    t = np.arange(len(current)) * 250e-6
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    return MeasuredRun.from_signals("run.csv", {"t": t, "x_ref": x, "x": x, "current": current})


def smooth_current(n: int = 20000) -> np.ndarray:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 250e-6
    current = 0.5 * np.sign(np.cos(2 * np.pi * 0.5 * t)) + rng.normal(0, 5e-3, n)
    current[5000:5006] += 0.8  # a breakaway spike: several samples, within the range
    return current


def test_one_absurd_sample_is_replaced_and_reported():
    current = smooth_current()
    current[1234] = 1e12
    fixed, warnings = screen_outliers(run_with(current), 0.001)
    assert abs(fixed.current[1234]) < 1.0
    assert len(warnings) == 1 and "current[1234] = 1e+12" in warnings[0]
    assert fixed.current[5002] == current[5002]  # the breakaway spike stays


def test_a_clean_run_is_left_alone():
    run = run_with(smooth_current())
    fixed, warnings = screen_outliers(run, 0.001)
    assert warnings == [] and fixed is run


def test_a_run_full_of_glitches_is_refused():
    current = smooth_current()
    current[::500] = 1e6
    with pytest.raises(MeasuredDataError, match="run.csv: column 'current': 40 outliers"):
        screen_outliers(run_with(current), 0.001)


def test_resolution_of_a_quantised_signal():
    rng = np.random.default_rng(0)
    x = np.round(np.cumsum(rng.normal(0, 3e-8, 5000)) / 1e-8) * 1e-8
    assert estimate_resolution(x) == pytest.approx(1e-8, rel=1e-6)
    assert estimate_resolution(np.cumsum(rng.normal(0, 3e-8, 5000))) == 0.0


def _bench_run(name: str, commanded: float, seed: int) -> MeasuredRun:
    """An open-loop run driven by its measured torque: the commanded step plus sensor noise."""
    t = np.arange(400) * 1e-3
    input_torque = np.where(t < 0.2, commanded, commanded + 0.01)  # N.m
    noise = np.random.default_rng(seed).normal(0.0, 0.02, t.size)
    signals = {
        "t": t,
        "motor_angle": 0.5 * t**2,
        "motor_speed": t,
        "input_torque": input_torque,
        "measured_torque": input_torque + noise,
    }
    return MeasuredRun.from_signals(name, signals).open_loop("measured_torque", 1e-3)


def test_runs_driven_by_their_measured_torque_repeat_their_commanded_input():
    """The repeats of a torque step are grouped by the torque commanded, not by the measured
    torque that drives the twin (a new value every sample, never the same twice)."""
    no_disturbance = SimpleNamespace(disturbance=None, command_disturbance=None)
    scenarios = [SimpleNamespace(**vars(no_disturbance)) for _ in range(4)]
    runs = [_bench_run("a1", 0.05, 1), _bench_run("b", -0.03, 2), _bench_run("a2", 0.05, 3)]
    runs.append(_bench_run("a3", 0.05, 4))
    assert repeat_groups(runs, scenarios, [0, 1, 2, 3]) == [[0, 2, 3]]
