"""Limit cycles and chattering are found on physics runs; settled loops are never flagged."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from emps_data import needs_emps_data

from twin_cosim.cli import main
from twin_cosim.controller_set import TABLE3
from twin_cosim.cosim import run_scenario
from twin_cosim.optimize.axis_problem import ObjectiveSpec
from twin_cosim.optimize.objective import Objective
from twin_cosim.oscillation import measure_oscillation, record_findings
from twin_cosim.run_checks import loop_warnings
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"


@pytest.fixture(scope="module")
def reference1():
    return load_scenario(SCENARIOS / "reference1.yaml")


def test_kp_pos_5000_is_a_limit_cycle_not_a_normal_run(plant, reference1):
    """The issue's case: +/-0.9 mm at about 27 Hz, inside the 1000 um divergence band."""
    tuned = dataclasses.replace(TABLE3["ft"], Kp_pos=5000.0)
    record = run_scenario(plant, reference1, tuned)
    assert float(abs(record["error"]).max()) * 1e6 < 1000.0  # not diverged
    unusable, warnings = loop_warnings(record, reference1)
    assert unusable
    assert any("limit cycle" in w for w in warnings), warnings


def test_kp_vel_30_chatters(plant, reference1):
    tuned = dataclasses.replace(TABLE3["ft"], Kp_vel=30.0)
    record = run_scenario(plant, reference1, tuned)
    unusable, warnings = loop_warnings(record, reference1)
    assert unusable
    assert [w for w in warnings if "chatters" in w] == warnings, warnings
    reversals = measure_oscillation(
        *(record[c] for c in ("t", "v_ref", "error", "current"))
    ).reversals_per_s
    assert reversals > 1000.0  # the current reverses at most samples (4000 per second)


@pytest.mark.parametrize("name", ["reference1", "reference2", "diagnosis", "sweep"])
@pytest.mark.parametrize("tuned", ["own", "ft", "ga", "ce", "sa"])
def test_shipped_scenarios_and_the_papers_sets_are_never_flagged(plant, name, tuned):
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    record = run_scenario(plant, scenario, None if tuned == "own" else TABLE3[tuned])
    assert loop_warnings(record, scenario) == (False, [])


@needs_emps_data
def test_the_emps_replay_is_not_flagged():
    from twin_cosim.plant import Plant

    scenario = load_scenario(SCENARIOS / "emps.yaml")
    with Plant(scenario.plant_fmu()) as emps:
        record = run_scenario(emps, scenario)
    assert record_findings(record, scenario.settings.current_limit) == []


def test_a_still_run_without_steady_phases_is_not_judged():
    """A reference that never holds still or moves evenly: nothing to judge, no finding."""
    t = np.arange(0.0, 1.0, 0.00025)
    chirp = {"t": t, "v_ref": np.sin(40 * t**2), "error": 1e-6 * np.sin(200 * t)}
    assert record_findings({**chirp, "current": np.sign(np.sin(8000 * t))}, 20.0) == []


def test_a_campaign_scores_a_chattering_candidate_as_a_failure_with_its_reason(reference1):
    objective = Objective(ObjectiveSpec((reference1,), None, iau_limit=None))
    try:
        result = objective(dataclasses.replace(TABLE3["ft"], Kp_vel=30.0).as_array())
    finally:
        objective.close()
    assert result["status"] == "unstable"
    assert "the current chatters" in result["reason"]
    assert result["fitness"] == 2e6


def test_simulate_warns_about_a_limit_cycle_and_exits_1(tmp_path, capsys):
    params = tmp_path / "kp_pos_5000.yaml"
    params.write_text(
        "".join(f"{k}: {v}\n" for k, v in TABLE3["ft"].as_dict().items()).replace(
            "Kp_pos: 66.6667", "Kp_pos: 5000.0"
        )
    )
    out = tmp_path / "out"
    status = main(
        ["simulate", "reference1", "--params", str(params), "--out", str(out), "--no-plots"]
    )
    assert status == 1
    err = capsys.readouterr().err
    assert "warning: the loop oscillates (a limit cycle)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert any("limit cycle" in w for w in summary["warnings"])
