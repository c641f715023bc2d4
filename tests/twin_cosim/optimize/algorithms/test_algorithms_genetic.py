"""Genetic algorithm: child counts and the MATLAB-style operators."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.optimize.algorithms.genetic import (
    GeneticAlgorithm,
    GeneticSettings,
    feasible_direction_mutation,
    rank_scaling,
    scattered_crossover,
    stochastic_uniform,
)


def test_child_counts_for_population_100_are_5_76_19():
    assert GeneticSettings().child_counts == (5, 76, 19)
    assert GeneticSettings(population_size=20).child_counts == (1, 15, 4)
    assert GeneticSettings().max_evaluations == 100 + 20 * 95


def test_batches_are_population_then_non_elite_children():
    opt = GeneticAlgorithm(6, 0)
    sizes = []
    for _ in range(3):
        x = opt.ask()
        sizes.append(len(x))
        opt.tell(np.sum(x**2, axis=1))
    assert sizes == [100, 95, 95]
    assert opt.ga_generation == 2
    assert len(opt.population) == 100


def test_elite_survive_unevaluated():
    opt = GeneticAlgorithm(6, 0)
    x = opt.ask()
    f = np.sum(x**2, axis=1)
    opt.tell(f)
    opt.ask()
    np.testing.assert_array_equal(opt._elite, x[np.argsort(f)[:5]])


def test_rank_scaling_is_inverse_sqrt_rank_and_ranks_inf_last():
    e = rank_scaling(np.array([3.0, np.inf, 1.0, 2.0]), total=10.0)
    raw = 1.0 / np.sqrt(np.array([3.0, 4.0, 1.0, 2.0]))
    np.testing.assert_allclose(e, 10.0 * raw / raw.sum())


def test_stochastic_uniform_selects_floor_or_ceil_of_expectation():
    rng = np.random.default_rng(0)
    for _ in range(20):
        expectation = rank_scaling(rng.random(30), total=40.0)
        counts = np.bincount(stochastic_uniform(rng, expectation, 40), minlength=30)
        assert counts.sum() == 40
        assert np.all(counts >= np.floor(expectation) - 1e-9)
        assert np.all(counts <= np.ceil(expectation) + 1e-9)


def test_scattered_crossover_takes_each_gene_from_a_parent():
    rng = np.random.default_rng(0)
    a, b = np.zeros((50, 6)), np.ones((50, 6))
    child = scattered_crossover(rng, a, b)
    assert set(np.unique(child)) == {0.0, 1.0}
    assert 0.4 < child.mean() < 0.6


def test_feasible_direction_mutation_stays_in_box():
    rng = np.random.default_rng(0)
    parents = np.vstack([np.full((200, 6), 0.5), rng.random((200, 6)), np.zeros((5, 6))])
    small = feasible_direction_mutation(rng, parents[:200], 0.1)
    np.testing.assert_allclose(np.linalg.norm(small - parents[:200], axis=1), 0.1)
    for step in (1.0, 0.3):
        child = feasible_direction_mutation(rng, parents, step)
        assert np.all((child >= 0.0) & (child <= 1.0))
        assert np.all(np.linalg.norm(child - parents, axis=1) <= step + 1e-12)
        assert np.mean(np.any(child != parents, axis=1)) > 0.9


def test_stall_stops_after_window_without_relative_change():
    opt = GeneticAlgorithm(6, 0)
    while opt.stop_reason is None:
        opt.tell(np.ones(len(opt.ask())))
    assert opt.stop_reason.startswith("stalled")
    assert opt.ga_generation == 10
    assert opt.evaluations == 100 + 10 * 95


def test_time_limit_is_optional_and_applied_when_set():
    assert GeneticSettings().time_limit_s is None
    opt = GeneticAlgorithm(6, 0, time_limit_s=1e-9)
    opt.tell(np.ones(len(opt.ask())))
    assert opt.stop_reason == "time limit 1e-09 s exceeded"


@pytest.mark.parametrize("seed", [0, 1])
def test_mutation_step_adapts(seed):
    opt = GeneticAlgorithm(6, seed)
    steps = []
    while opt.stop_reason is None:
        x = opt.ask()
        opt.tell(np.sum((x - 0.3) ** 2, axis=1))
        steps.append(opt.step)  # the step for the next generation
    assert steps[:2] == [1.0, 1.0]  # generations 1 and 2 use step 1, as MATLAB
    assert min(steps) < 1e-2
