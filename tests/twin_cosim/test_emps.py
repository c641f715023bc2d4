"""The EMPS benchmark with the project's machinery: loader, replay of the estimation run, diagnosis.

Tests that need the benchmark's data skip where it is absent (the folder given by
TWIN_COSIM_DATA, else ../shared/data/emps beside the repository).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from emps_data import EMPS_DATA, needs_emps_data
from scipy.io import savemat

from twin_cosim.cosim import run_scenario
from twin_cosim.environment import DATA_ENV
from twin_cosim.measured import MeasuredDataError, read_measured
from twin_cosim.metrics import compare_with_measured
from twin_cosim.plant import Plant
from twin_cosim.scenario import ScenarioError, load_scenario

ROOT = Path(__file__).resolve().parents[2]
DATA = EMPS_DATA
needs_data = needs_emps_data


def fake_mat(path: Path, pulses: bool) -> Path:
    t = np.arange(200) * 1e-3
    data = {
        "t": t[:, None],
        "qg": (1e-3 * t)[:, None],
        "qm": (1e-3 * t)[:, None],
        "vir": np.ones((200, 1)),
        "gtau": np.array([[35.15]]),
        "kp": np.array([[160.18]]),
        "kv": np.array([[243.45]]),
    }
    if pulses:
        data["pulses_N"] = np.where(t > 0.1, 1.0, 0.0)[:, None]
    savemat(path, data)
    return path


@pytest.mark.parametrize("pulses", [False, True])
def test_mat_loader_reads_the_published_layout(tmp_path, pulses):
    run = read_measured(fake_mat(tmp_path / "run.mat", pulses))
    assert run.period == pytest.approx(1e-3)
    assert run.scalars["gtau"] == pytest.approx(35.15)
    assert ("pulses_N" in run.record) == pulses


def test_mat_loader_errors(tmp_path):
    path = tmp_path / "bad.mat"
    savemat(path, {"t": np.arange(200.0), "qg": np.zeros(200)})
    with pytest.raises(MeasuredDataError, match=r"bad.mat: missing variable\(s\) \['qm', 'vir'\]"):
        read_measured(path)
    other = tmp_path / "run.txt"
    other.write_text("")
    with pytest.raises(MeasuredDataError, match="unknown measured-run type"):
        read_measured(other)


def emps_scenario_with(tmp_path: Path, disturbance: str | None = None):
    """scenarios/emps.yaml on a fake run with pulses, with another disturbance convention."""
    fake_mat(tmp_path / "run.mat", True)
    text = (ROOT / "scenarios" / "emps.yaml").read_text()
    text = text.replace("measured: ../../shared/data/emps/DATA_EMPS.mat", "measured: run.mat")
    if disturbance is not None:
        start = text.index("  disturbance: {")
        end = text.index("\n", start)
        text = text[:start] + f"  disturbance: {disturbance}" + text[end:]
    scenario_file = tmp_path / "s.yaml"
    scenario_file.write_text(text)
    return load_scenario(scenario_file)


def test_the_emps_pulses_are_added_to_the_recorded_command(tmp_path):
    """The benchmark's convention (scenarios/emps.yaml): pulses in V on the drive command."""
    scenario = emps_scenario_with(tmp_path)
    assert scenario.disturbance is None
    assert scenario.command_disturbance[-1] == pytest.approx(1.0)
    assert scenario.command_disturbance[50] == 0.0
    assert scenario.disturbance_in_record


def test_pulses_can_enter_at_the_disturbance_input(tmp_path):
    scenario = emps_scenario_with(
        tmp_path, "{variable: pulses_N, gain: -35.15065188, enters: disturbance_input}"
    )
    assert scenario.command_disturbance is None and not scenario.disturbance_in_record
    assert scenario.disturbance[-1] == pytest.approx(-35.15065188)
    assert scenario.disturbance[50] == 0.0


@pytest.mark.parametrize(
    ("convention", "message"),
    [
        ("{variable: pulses_N, enters: drive}", "reference.disturbance.enters: expected one of"),
        (
            "{variable: pulses_N, enters: disturbance_input, in_recorded_command: true}",
            "in_recorded_command: expected false unless the disturbance enters at the command",
        ),
        ("{variable: pulses_N, in_recorded_command: 1}", "expected true or false"),
    ],
)
def test_a_bad_signal_convention_is_named(tmp_path, convention, message):
    with pytest.raises(ScenarioError, match=message):
        emps_scenario_with(tmp_path, convention)


@needs_data
def test_replay_reproduces_the_published_position_gap():
    scenario = load_scenario(ROOT / "scenarios" / "emps.yaml")
    run = read_measured(scenario.measured)
    with Plant(scenario.plant_fmu()) as plant:
        record = run_scenario(plant, scenario)
    figures = compare_with_measured(record, run.t, run.x, run.current)
    assert figures["position_rms_gap_um"] == pytest.approx(2.58, rel=0.05)  # published: 2.58 um
    assert figures["current_relative_error_pct"] < 10.0  # published model: 5.85 % (see docs)


@needs_data
@pytest.mark.slow
def test_diagnosis_runs_on_the_real_data(twin_cli, tmp_path):
    result = twin_cli(
        "diagnose", "scenarios/emps.yaml", "--measured", str(DATA), "--out", str(tmp_path), "--json"
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["gap"]["significant"]
    assert summary["accepted"]
    for step in summary["steps"]:
        assert step["holdout_gap_after_um"] < step["holdout_gap_before_um"]


def twin_mat(tmp_path: Path, name: str, frequency: float, pulses: bool) -> Path:
    """A .mat run of the EMPS twin itself on a sine reference (with force pulses or not)."""
    t = np.arange(3000) * 1e-3
    reference = 0.02 * (1 - np.cos(2 * np.pi * frequency * t))
    pulse = np.where((t > 1.0) & (t < 1.2), 0.5, 0.0) if pulses else np.zeros_like(t)
    draft = {
        "t": t[:, None],
        "qg": reference[:, None],
        "qm": reference[:, None],
        "vir": np.zeros((3000, 1)),
        "pulses_N": pulse[:, None],
    }
    path = tmp_path / name
    savemat(path, draft)
    scenario_file = tmp_path / f"{name}.yaml"
    scenario_file.write_text(
        (ROOT / "scenarios" / "emps.yaml")
        .read_text()
        .replace("../../shared/data/emps/DATA_EMPS.mat", name)
    )
    scenario = load_scenario(scenario_file)
    with Plant(scenario.plant_fmu()) as plant:
        record = run_scenario(plant, scenario, plant_overrides={"load_position_start": 0.0})
    savemat(
        path,
        {
            **draft,
            "qm": record["x"][:, None],
            "vir": record["current"][:, None],
        },
    )
    return path


def diagnose_with_holdout(twin_cli, tmp_path: Path, train: Path, held: Path) -> dict:
    """``twin diagnose`` of the scenario of ``twin_mat``: train on one run, judge on another."""
    result = twin_cli(
        "diagnose",
        str(tmp_path / "train.mat.yaml"),
        "--measured",
        str(train),
        "--holdout",
        str(held),
        "--out",
        str(tmp_path / "r"),
        "--json",
    )
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


@pytest.mark.slow
def test_holdout_run_follows_its_own_reference_and_pulses(twin_cli, tmp_path):
    """A held-out run of another trajectory, with pulses, is replayed with both: no gap."""
    train = twin_mat(tmp_path, "train.mat", 0.5, pulses=False)
    held = twin_mat(tmp_path, "held.mat", 0.8, pulses=True)
    summary = diagnose_with_holdout(twin_cli, tmp_path, train, held)
    assert summary["holdout"] == [str(held)]
    assert summary["gap"]["validation_figures"]["rms_um"] < 0.05
    assert summary["accepted"] == []


@pytest.mark.slow
def test_synthetic_validation_run_with_pulses_leaves_only_noise(twin_cli, tmp_path):
    """The signal convention end to end: a validation-like run made by the twin itself (pulses
    added to the command, recorded in it) leaves a held-out command residual at noise level."""
    from twin_cosim.emps_runs import pulse_template

    train = twin_mat(tmp_path, "train.mat", 0.5, pulses=False)
    gains = {"kp": 160.18, "kv": 243.45, "gtau": 35.15065188}
    template = pulse_template(tmp_path / "template.mat", 4, gains, duration=6.0, pulse_height=3.0)
    held = tmp_path / "held.mat"
    made = twin_cli(
        "synth",
        str(tmp_path / "train.mat.yaml"),
        "--follow",
        str(template),
        "--out",
        str(held),
        "--noise-current",
        "0.005",
        "--seed",
        "2",
    )
    assert made.returncode == 0, made.stderr
    run = read_measured(held)
    assert np.abs(run.record["pulses_N"]).max() == pytest.approx(3.0)  # the pulses are there
    summary = diagnose_with_holdout(twin_cli, tmp_path, train, held)
    (held_run,) = summary["gap"]["holdout_runs"]
    assert held_run["current_rms_before"] < 0.0075  # the 5 mV of white noise, not the pulses
    errors = summary["gap"]["holdout_relative_errors_before"]
    assert set(errors) == {"position", "velocity", "acceleration", "force"}
    assert errors["force"] < 1.0 and errors["position"] < 0.01
    assert summary["accepted"] == []


def simulate_copy(tmp_path: Path, *options: str) -> subprocess.CompletedProcess:
    """``twin simulate`` on a copy of emps.yaml away from the data, without TWIN_COSIM_DATA."""
    copy = tmp_path / "emps.yaml"
    copy.write_text((ROOT / "scenarios" / "emps.yaml").read_text())
    env = {k: v for k, v in os.environ.items() if k != DATA_ENV}
    command = [sys.executable, "-m", "twin_cosim", "simulate", str(copy), *options]
    command += ["--out", str(tmp_path / "out")]
    return subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, env=env)


def test_missing_data_says_what_it_is_and_where_to_get_it(tmp_path):
    result = simulate_copy(tmp_path)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    for words in (
        "DATA_EMPS.mat not found",
        "EMPS benchmark",
        "Janot, M. Gautier, M. Brunot",
        "nonlinearbenchmark.org",
        "--data DIR",
        f"{DATA_ENV}=DIR",
    ):
        assert words in result.stderr


@needs_data
def test_data_option_points_at_the_data(tmp_path):
    result = simulate_copy(tmp_path, "--data", str(DATA.parent), "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["validation"]["measured"] == str(DATA)
    assert summary["validation"]["position_rms_gap_um"] == pytest.approx(2.58, rel=0.05)
