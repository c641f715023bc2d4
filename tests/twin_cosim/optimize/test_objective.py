"""The objective: E_pk for valid runs; penalties with reasons for violations and failures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin_cosim.controller import TunedParameters
from twin_cosim.cosim import run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.objective import EvaluationTask, Objective, ObjectiveSpec
from twin_cosim.paper import TABLE3
from twin_cosim.scenario import load_scenario

REFERENCE1 = str(Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml")


@pytest.fixture(scope="module")
def objective():
    instance = Objective(ObjectiveSpec(REFERENCE1, None, iau_limit=None))
    yield instance
    instance.close()


def test_valid_candidate_scores_its_epk(objective, plant):
    result = objective(TABLE3["ga"].as_array())
    record = run_scenario(plant, load_scenario(REFERENCE1), TABLE3["ga"])
    assert result["status"] == "ok"
    assert result["fitness"] == compute_metrics(record).E_pk_um


def test_iau_cap_violation_is_penalised(objective):
    spec = ObjectiveSpec(REFERENCE1, None, iau_limit=1.0)  # A.s, far below what the run needs
    capped = Objective(spec)
    result = capped(TABLE3["ft"].as_array())
    capped.close()
    assert result["status"] == "violation"
    assert "above the cap" in result["reason"]
    assert result["fitness"] == pytest.approx(1e6 + result["metrics"]["E_pk_um"])


def test_unstable_candidate_is_stopped_and_penalised(objective):
    # A position gain far beyond the speed loop's bandwidth: the error runs away.
    result = objective(np.array([20000.0, 0.05, 0.0, 0.0, 0.01, 0.1]))
    assert result["status"] == "unstable"
    assert "exceeded 1000 um" in result["reason"]
    assert result["fitness"] == 2e6
    assert result["metrics"] is None


def test_refused_parameters_are_a_failure(objective):
    result = objective(np.array([66.0, 0.3, 0.008, 0.7, 0.0, 0.1]))  # PP3 = 0
    assert result["status"] == "failed"
    assert "PP3 must be > 0" in result["reason"]


SHORT = """
name: short
reference:
  segments:
    - dwell: 0.1
    - ramp: {velocity: 0.01, acceleration: 0.1, duration: 0.4}
    - ramp: {velocity: -0.01, acceleration: 0.1, duration: 0.4}
    - ramp: {velocity: 0.0, acceleration: 0.1, duration: 0.1}
    - dwell: 0.1
"""
SAMPLES = ({}, {"backlash": 1.5, "coulomb_friction": 1.2}, {"load_inertia": 0.8})


@pytest.fixture(scope="module")
def two_scenarios(tmp_path_factory):
    folder = tmp_path_factory.mktemp("robust")
    (folder / "a.yaml").write_text(SHORT)
    (folder / "b.yaml").write_text(
        SHORT.replace("acceleration: 0.1", "acceleration: 0.3").replace("name: short", "name: b")
    )
    return str(folder / "a.yaml"), str(folder / "b.yaml")


def single_run_fitness(scenario_file, factors, x, plant):
    scenario = load_scenario(scenario_file)
    nominal = {**plant.start_values(), **scenario.plant_parameters}
    overrides = {name: nominal[name] * f for name, f in factors.items()}
    record = run_scenario(plant, scenario, TunedParameters.from_array(x), plant_overrides=overrides)
    return compute_metrics(record).E_pk_um


@pytest.mark.parametrize("aggregate", ["worst", "mean"])
def test_robust_fitness_is_the_worst_or_mean_of_separate_runs(two_scenarios, plant, aggregate):
    first, second = two_scenarios
    spec = ObjectiveSpec(first, None, None, None, (second,), (None,), SAMPLES, aggregate)
    robust = Objective(spec)
    x = TABLE3["ft"].as_array()
    result = robust(x)
    robust.close()
    singles = [single_run_fitness(f, s, x, plant) for f in two_scenarios for s in SAMPLES]
    assert len(result["metrics"]["runs"]) == 6
    expected = max(singles) if aggregate == "worst" else sum(singles) / len(singles)
    assert result["fitness"] == pytest.approx(expected, rel=1e-12)
    assert len(set(singles)) > 1  # the samples and scenarios do change the runs


@pytest.mark.parametrize("aggregate", ["worst", "mean"])
def test_early_stop_gives_a_lower_bound_above_the_cutoff(two_scenarios, aggregate):
    first, second = two_scenarios
    spec = ObjectiveSpec(first, None, None, None, (second,), (None,), SAMPLES, aggregate)
    robust = Objective(spec)
    x = TABLE3["ft"].as_array()
    full = robust(x)
    for share in (0.3, 0.7, 0.95):
        cutoff = share * full["fitness"]
        stopped = robust(EvaluationTask(x, cutoff))
        assert stopped["status"] == "stopped"
        assert cutoff < stopped["fitness"] <= full["fitness"]
        assert stopped["steps"] < full["steps"]
    assert robust(EvaluationTask(x, 1.01 * full["fitness"]))["fitness"] == full["fitness"]
    robust.close()
