"""Exact early stopping: the same campaign, fewer simulated steps; the order of a generation,
the likeliest best first."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
import tqdm
from scenario_texts import scenario_text

from twin_cosim.optimize import early_stop
from twin_cosim.optimize.algorithms import make_optimizer
from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.early_stop import (
    MISS_FACTOR,
    NEIGHBOURS,
    EvaluationTask,
    OwnEvaluations,
    elite_cutoff,
    kth_best,
    likeliest_best_first,
    lower_bound_above,
    window_spans_run,
)
from twin_cosim.workers import BoundPool

SHORT = scenario_text(optimize="methods: {ce: {population_size: 10, elite_fraction: 0.2}}")


def test_elite_cutoff_is_the_elite_count_th_best_known():
    ce = make_optimizer("ce", 6, 0, population_size=10, elite_fraction=0.2)  # elite of 2
    assert elite_cutoff(ce, 10, np.array([5.0])) == math.inf
    assert elite_cutoff(ce, 10, np.array([5.0, 3.0, 4.0])) == 4.0
    assert elite_cutoff(make_optimizer("cmaes", 6, 0), 10, np.array([1.0, 2.0])) == math.inf
    assert lower_bound_above(4.0) > 4.0


def test_kth_best_needs_k_values():
    assert kth_best([5.0, 3.0, 4.0], 2) == 4.0
    assert kth_best([5.0], 2) == math.inf
    assert kth_best([5.0], 0) == math.inf


class Recorded:
    """An evaluation that answers the fitness it is given and keeps the cutoffs it saw."""

    def __init__(self) -> None:
        self.cutoffs: list[float] = []

    def __call__(self, fitness: float, status: str = "ok"):
        def evaluate(x, cutoff_um):
            self.cutoffs.append(cutoff_um)
            return {"fitness": fitness, "status": status}

        return evaluate


def test_a_worker_lowers_the_cutoff_by_its_own_complete_values_of_the_generation():
    own, seen = OwnEvaluations(), Recorded()
    x = np.zeros(6)
    own.evaluate(EvaluationTask(x, 10.0, "g", 1), seen(4.0))
    own.evaluate(EvaluationTask(x, 10.0, "g", 1), seen(3.0, "stopped"))  # a bound, no value
    own.evaluate(EvaluationTask(x, 2.0, "g", 1), seen(6.0))  # the task's cutoff is lower
    own.evaluate(EvaluationTask(x, 10.0, "g", 1), seen(5.0))
    own.evaluate(EvaluationTask(x, 10.0, "h", 1), seen(1.0))  # another generation starts over
    own.evaluate(EvaluationTask(x, 10.0, "h", 2), seen(7.0))  # an elite of 2: one value known
    own.evaluate(EvaluationTask(x, 10.0, "h", 2), seen(7.0))
    own.evaluate(x, seen(1.0))  # a plain candidate has no cutoff
    assert seen.cutoffs == [10.0, 4.0, 2.0, 4.0, 10.0, 10.0, 7.0, math.inf]


def test_a_task_without_a_generation_keeps_its_cutoff():
    own, seen = OwnEvaluations(), Recorded()
    for _ in range(2):
        own.evaluate(EvaluationTask(np.zeros(6), 10.0), seen(1.0))
    assert seen.cutoffs == [10.0, 10.0]


def test_window_spans_run():
    assert window_spans_run((0.0, None), 2.0)
    assert not window_spans_run((0.5, None), 2.0)
    assert not window_spans_run((0.0, 1.0), 2.0)


@pytest.fixture(scope="module")
def short_scenario(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("scenario") / "short.yaml"
    path.write_text(SHORT)
    return str(path)


def entries(folder):
    lines = (folder / "evaluations.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines]


def test_early_stop_changes_nothing_but_the_cost(short_scenario, tmp_path):
    results = {}
    for name, early, workers in (("full", False, 1), ("early", True, 1), ("pool", True, 2)):
        spec = CampaignSpec(short_scenario, "ce", seed=5, budget=60, early_stop=early)
        results[name] = run_campaign(
            AxisProblem.resolve(spec), tmp_path / name, workers=workers, progress=False
        )
    full, early = results["full"], results["early"]
    for other in (early, results["pool"]):
        assert other.best_params == full.best_params
        assert other.fitness == full.fitness
        assert other.evaluations == full.evaluations == 60
    steps = {name: sum(e["steps"] for e in entries(tmp_path / name)) for name in ("full", "early")}
    assert steps["early"] < 0.8 * steps["full"]
    stopped = [e for e in entries(tmp_path / "early") if e["status"] == "stopped"]
    assert stopped
    exact = {e["key"]: e["fitness"] for e in entries(tmp_path / "full")}
    for entry in stopped:  # a lower bound of the value the full run found
        assert entry["fitness"] <= exact[entry["key"]]


def test_a_process_pool_has_one_candidate_waiting_beyond_its_workers(
    short_scenario, tmp_path, monkeypatch
):
    asked = []
    given = BoundPool.imap

    def recorded(pool, tasks, in_flight=None):
        asked.append(in_flight)
        return given(pool, tasks, in_flight)

    monkeypatch.setattr(BoundPool, "imap", recorded)
    spec = CampaignSpec(short_scenario, "ce", seed=5, budget=20)
    run_campaign(AxisProblem.resolve(spec), tmp_path / "pool", workers=2, progress=False)
    assert set(asked) == {3}
    asked.clear()
    run_campaign(
        AxisProblem.resolve(dataclasses.replace(spec, early_stop=False)),
        tmp_path / "all",
        workers=2,
        progress=False,
    )
    assert set(asked) == {None}  # without early stopping a generation goes out at once


def test_a_guess_too_low_costs_runs_again_and_changes_nothing(
    short_scenario, tmp_path, monkeypatch
):
    spec = CampaignSpec(short_scenario, "ce", seed=5, budget=60)
    full = run_campaign(
        AxisProblem.resolve(dataclasses.replace(spec, early_stop=False)),
        tmp_path / "full",
        progress=False,
        workers=1,
    )
    monkeypatch.setattr(early_stop, "guess_above", lambda cutoff: 0.01 * cutoff)
    counted = []
    monkeypatch.setattr(tqdm.tqdm, "update", lambda bar, n=1: counted.append(n))
    low = run_campaign(AxisProblem.resolve(spec), tmp_path / "low", workers=2, progress=False)
    assert (low.best_params, low.fitness, low.evaluations) == (
        full.best_params,
        full.fitness,
        full.evaluations,
    )
    logged = entries(tmp_path / "low")
    keys = [e["key"] for e in logged]
    again = {k for k in keys if keys.count(k) > 1}
    assert again  # stopped below the generation's cutoff, then run again
    assert sum(counted) == 60  # the progress bar counts each candidate once
    for key in again:
        first = next(e for e in logged if e["key"] == key)
        assert first["status"] == "stopped"
    thrice = [k for k in again if keys.count(k) == 3]
    assert thrice  # a second guess still too low: a third pass, without a guess, ends it
    for key in thrice:
        first, second, third = (e for e in logged if e["key"] == key)
        assert (first["status"], second["status"]) == ("stopped", "stopped")
        assert second["fitness"] == pytest.approx(MISS_FACTOR * first["fitness"], rel=1e-12)
        assert third["status"] != "stopped" or third["fitness"] > second["fitness"]


def test_a_resumed_generation_runs_a_lower_bound_below_its_cutoff_again(short_scenario, tmp_path):
    spec = CampaignSpec(short_scenario, "ce", seed=5, budget=60)
    done = run_campaign(AxisProblem.resolve(spec), tmp_path / "c", workers=1, progress=False)
    log = tmp_path / "c" / "evaluations.jsonl"
    logged = entries(tmp_path / "c")
    stopped = next(i for i, e in enumerate(logged) if e["status"] == "stopped")
    logged[stopped]["fitness"] = 0.0  # a lower bound that cannot rule the candidate out
    log.write_text("".join(json.dumps(e) + "\n" for e in logged))
    resumed = run_campaign(
        AxisProblem.resolve(spec), tmp_path / "c", workers=1, resume=True, progress=False
    )
    assert (resumed.best_params, resumed.fitness) == (done.best_params, done.fitness)
    again = entries(tmp_path / "c")[len(logged) :]
    assert [e["key"] for e in again] == [logged[stopped]["key"]]
    assert again[0]["fitness"] > 0.0


def test_without_evaluations_the_order_is_the_one_asked_in():
    assert likeliest_best_first(np.zeros((4, 2)), np.empty((0, 2)), np.empty(0)).tolist() == [
        0,
        1,
        2,
        3,
    ]


def test_candidates_near_good_evaluations_go_first():
    # a valley at the origin: fitness grows with the distance from it
    rng = np.random.default_rng(0)
    evaluated = rng.uniform(-1.0, 1.0, size=(200, 2))
    fitness = 1.0 + np.linalg.norm(evaluated, axis=1)
    candidates = np.array([[0.9, 0.9], [0.05, 0.0], [-0.5, 0.4], [0.0, -0.2]])
    order = likeliest_best_first(candidates, evaluated, fitness)
    assert order.tolist() == [1, 3, 2, 0]


def test_equal_predictions_keep_the_order_asked_in():
    evaluated = np.zeros((NEIGHBOURS, 3))
    order = likeliest_best_first(np.ones((5, 3)), evaluated, np.full(NEIGHBOURS, 2.0))
    assert order.tolist() == [0, 1, 2, 3, 4]
