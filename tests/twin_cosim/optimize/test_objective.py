"""The objective: E_pk for valid runs; penalties with reasons for violations and failures."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import scenario_text

from twin_cosim.controller import TunedParameters
from twin_cosim.controller_set import TABLE3
from twin_cosim.cosim import run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.axis_problem import ObjectiveSpec
from twin_cosim.optimize.early_stop import EvaluationTask, lower_bound_above
from twin_cosim.optimize.objective import Objective
from twin_cosim.scenario import load_scenario

REFERENCE1 = str(Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml")


def loaded(*files: str) -> tuple:
    """The scenarios of ``files``, resolved as a campaign sends them to its workers."""
    return tuple(load_scenario(f) for f in files)


@pytest.fixture(scope="module")
def objective():
    instance = Objective(ObjectiveSpec(loaded(REFERENCE1), None, iau_limit=None))
    yield instance
    instance.close()


def test_valid_candidate_scores_its_epk(objective, plant):
    result = objective(TABLE3["ga"].as_array())
    record = run_scenario(plant, load_scenario(REFERENCE1), TABLE3["ga"])
    assert result["status"] == "ok"
    assert result["fitness"] == compute_metrics(record).E_pk_um


def test_the_record_of_a_run_is_the_run_a_candidate_is_scored_on(objective, plant):
    own = objective.record(None)
    assert compute_metrics(own).E_pk_um == objective.reference_of(0)["E_pk_um"]
    record = objective.record(TABLE3["ga"].as_array())
    expected = run_scenario(plant, load_scenario(REFERENCE1), TABLE3["ga"])
    assert compute_metrics(record).E_pk_um == compute_metrics(expected).E_pk_um


def test_a_worse_candidate_of_the_same_generation_stops_at_the_better_ones_value(objective):
    better = objective(EvaluationTask(TABLE3["ga"].as_array(), math.inf, "g", 1))
    worse = objective(EvaluationTask(TABLE3["ft"].as_array(), math.inf, "g", 1))
    assert better["status"] == "ok"
    assert worse["status"] == "stopped"
    assert worse["fitness"] == lower_bound_above(better["fitness"])
    alone = objective(EvaluationTask(TABLE3["ft"].as_array(), math.inf, "h", 1))
    assert alone["status"] == "ok"  # in another generation, the better one's value is no cutoff
    assert alone["fitness"] > worse["fitness"]
    assert alone["steps"] > worse["steps"]


def test_iau_cap_violation_is_penalised(objective):
    # An IAU limit of 1 A.s, far below what the run needs.
    spec = ObjectiveSpec(loaded(REFERENCE1), None, iau_limit=1.0)
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


SHORT = scenario_text(speed=0.01, acceleration=0.1, move=0.4)
SAMPLES = ({}, {"backlash": 1.5, "coulomb_friction": 1.2}, {"load_inertia": 0.8})


@pytest.fixture(scope="module")
def two_scenarios(tmp_path_factory):
    folder = tmp_path_factory.mktemp("robust")
    (folder / "a.yaml").write_text(SHORT)
    (folder / "b.yaml").write_text(scenario_text("b", speed=0.01, acceleration=0.3, move=0.4))
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
    spec = ObjectiveSpec(loaded(first, second), None, None, (), SAMPLES, aggregate)
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
    spec = ObjectiveSpec(loaded(first, second), None, None, (), SAMPLES, aggregate)
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


def test_relative_scales_multiply_each_runs_epk(two_scenarios, plant):
    first, second = two_scenarios
    scales = tuple(0.5 + 0.25 * k for k in range(6))
    spec = ObjectiveSpec(loaded(first, second), None, None, (), SAMPLES, "worst", scales)
    robust = Objective(spec)
    x = TABLE3["ga"].as_array()
    result = robust(x)
    robust.close()
    singles = [single_run_fitness(f, s, x, plant) for f in two_scenarios for s in SAMPLES]
    assert result["fitness"] == pytest.approx(
        max(a * b for a, b in zip(scales, singles, strict=True))
    )
    assert result["metrics"]["E_pk_um"] == pytest.approx(max(singles))  # metrics stay in um


def test_a_case_count_mismatch_is_refused(two_scenarios):
    first, second = two_scenarios
    with pytest.raises(ValueError, match="6 cases .* got 2 IAU limits"):
        Objective(ObjectiveSpec(loaded(first, second), None, None, (1.0, 1.0), SAMPLES))


def test_each_case_has_its_own_iau_limit(two_scenarios):
    first, second = two_scenarios
    probe = Objective(ObjectiveSpec(loaded(first, second), None, None, (), SAMPLES))
    references = [probe.reference_of(case) for case in range(len(probe.cases))]
    probe.close()
    iau = [r["IAU"] for r in references]
    assert max(iau) > 1.02 * min(iau)  # the samples and scenarios need different currents
    own = tuple(1.001 * value for value in iau)
    capped = Objective(ObjectiveSpec(loaded(first, second), None, None, own, SAMPLES))
    assert capped(TABLE3["ft"].as_array())["status"] == "ok"
    capped.close()
    # One limit for every case, the nominal first case's, penalises the samples needing more.
    shared = Objective(ObjectiveSpec(loaded(first, second), None, 1.001 * iau[0], (), SAMPLES))
    assert shared(TABLE3["ft"].as_array())["status"] == "violation"
    shared.close()


def test_the_case_that_stopped_a_candidate_runs_first_next(two_scenarios):
    first, second = two_scenarios
    spec = ObjectiveSpec(loaded(first, second), None, None, (), SAMPLES, "worst")
    robust = Objective(spec)
    x = TABLE3["ft"].as_array()
    full = robust(x)
    worst = int(np.argmax([r["E_pk_um"] for r in full["metrics"]["runs"]]))
    cutoff = 0.99 * full["fitness"]
    fresh = Objective(spec)  # the case order of a new objective: the first case first
    first_try = fresh(EvaluationTask(x, cutoff))
    second_try = fresh(EvaluationTask(x, cutoff))
    fresh.close()
    assert worst != 0
    assert first_try["fitness"] == second_try["fitness"]  # the bound does not depend on order
    assert second_try["steps"] < first_try["steps"]  # the stopping case ran first
    assert robust(EvaluationTask(x, cutoff))["steps"] == second_try["steps"]
    robust.close()


def test_a_settling_weight_adds_the_runs_settling_time():
    """--objective settling=W: the fitness is E_pk + W settling_ms (um); the paper's objective,
    W = 0, is E_pk alone."""
    weighted = Objective(ObjectiveSpec(loaded(REFERENCE1), None, None, settling_weight=0.1))
    try:
        result = weighted(TABLE3["ga"].as_array())
    finally:
        weighted.close()
    metrics = result["metrics"]
    assert metrics["settling_ms"] > 10.0
    assert result["fitness"] == pytest.approx(metrics["E_pk_um"] + 0.1 * metrics["settling_ms"])
