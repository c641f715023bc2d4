"""Cross-entropy method: dynamic smoothing, elite statistics, truncation, stopping rules.

Genetic algorithm: child counts and the MATLAB-style operators.

Simulated annealing: bound redraw, cooling, reannealing, chains and stopping rules.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.optimize.algorithms.paper_methods import (
    CrossEntropy,
    GeneticAlgorithm,
    GeneticSettings,
    SimulatedAnnealing,
    dynamic_beta,
    estimate_sensitivity,
    feasible_direction_mutation,
    rank_scaling,
    reanneal_parameters,
    redraw_out_of_bounds,
    sample_truncated_normal,
    scattered_crossover,
    stochastic_uniform,
)

SHIFT = np.array([0.3, 0.7, 0.45, 0.62, 0.2, 0.81])


def sphere(x):
    return np.sum((x - SHIFT) ** 2, axis=1)


def run(opt):
    while opt.stop_reason is None:
        opt.tell(sphere(opt.ask()))
    return opt


def test_dynamic_beta_matches_hand_computation():
    # beta_t = 0.4 - 0.4 (1 - 1/t)^0.1:  t=1: 0^0.1 = 0;  t=2: 0.5^0.1 = 0.9330329915;
    # t=3: (2/3)^0.1 = 0.9602645008.
    assert dynamic_beta(0.4, 0.1, 1) == 0.4
    assert dynamic_beta(0.4, 0.1, 2) == pytest.approx(0.4 * (1 - 0.9330329915), rel=1e-9)
    assert dynamic_beta(0.4, 0.1, 3) == pytest.approx(0.4 * (1 - 0.9602645008), rel=1e-9)


def test_single_elite_updates_mean_and_shrinks_sigma_by_dynamic_beta():
    """Table 2: ceil(0.01 * 20) = 1 elite, whose spread is 0 (no NaN from ddof)."""
    opt = CrossEntropy(6, 0)
    sigma = 0.3
    mu = np.full(6, 0.5)
    for beta_t in (0.4, 0.026786803385, 0.015894199683):
        x = opt.ask()
        f = sphere(x)
        opt.tell(f)
        mu = 0.6 * x[np.argmin(f)] + 0.4 * mu
        sigma *= 1.0 - beta_t
        np.testing.assert_allclose(opt.mu, mu, rtol=1e-12)
        np.testing.assert_allclose(opt.sigma, sigma, rtol=1e-9)


def test_x0_is_initial_mean():
    x0 = np.linspace(0.1, 0.9, 6)
    np.testing.assert_array_equal(CrossEntropy(6, 0, x0=x0).mu, x0)
    np.testing.assert_array_equal(CrossEntropy(6, 0).mu, np.full(6, 0.5))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_paper_settings_improve_substantially(seed):
    """Centre value 0.283, mean of a random point 0.78; worst of seeds 0-19 measured 0.028."""
    opt = run(CrossEntropy(6, seed))
    assert opt.best[1] < 0.1
    assert "no improvement" in opt.stop_reason


def test_paper_q_barely_shrinks_sigma_but_q5_converges():
    """With stall stop disabled: q = 0.1 keeps sigma near half its start for all 100
    generations (2,000 evaluations, epsilon never reached); q = 5 collapses it."""
    paper = run(CrossEntropy(6, 0, stall_generations=100))
    assert paper.stop_reason == "generation limit 100 reached"
    assert paper.evaluations == 2000
    assert 0.1 < paper.sigma.max() < 0.3 * 0.6
    fast = run(CrossEntropy(6, 0, q=5.0, stall_generations=100))
    assert fast.sigma.max() < 1e-3
    assert fast.best[1] < 1e-6 < paper.best[1]


def test_epsilon_stop_when_sigma_collapses():
    opt = run(CrossEntropy(6, 0, beta=1.0))
    assert opt.generation == 1
    assert opt.stop_reason.startswith("converged: max sigma 0")
    assert np.all(opt.sigma == 0.0)


def test_truncated_normal_stays_in_box_with_half_normal_mean_at_a_face():
    rng = np.random.default_rng(0)
    mu = np.array([0.0, 1.0, 0.5, 0.5])
    sigma = np.array([0.1, 0.1, 0.0, 50.0])
    x = sample_truncated_normal(rng, mu, sigma, 20_000)
    assert np.all((x >= 0.0) & (x <= 1.0))
    half_normal_mean = 0.1 * np.sqrt(2.0 / np.pi)
    assert x[:, 0].mean() == pytest.approx(half_normal_mean, abs=2e-3)
    assert x[:, 1].mean() == pytest.approx(1.0 - half_normal_mean, abs=2e-3)
    assert np.all(x[:, 2] == 0.5)
    assert x[:, 3].mean() == pytest.approx(0.5, abs=1e-2)  # nearly uniform


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


def test_redraw_keeps_points_between_bound_and_previous_value():
    rng = np.random.default_rng(0)
    previous = rng.random((500, 6))
    trial = previous + rng.normal(0.0, 1.0, previous.shape)
    repaired = redraw_out_of_bounds(rng, trial, previous)
    below, above, inside = trial < 0.0, trial > 1.0, (trial >= 0.0) & (trial <= 1.0)
    assert below.any() and above.any()
    assert np.all((repaired >= 0.0) & (repaired <= 1.0))
    assert np.all(repaired[below] <= previous[below])
    assert np.all(repaired[above] >= previous[above])
    np.testing.assert_array_equal(repaired[inside], trial[inside])


def test_every_asked_point_is_inside_although_early_steps_span_the_box():
    opt = SimulatedAnnealing(6, 0, budget=4000, function_tolerance=0.0)
    first_moves = []
    while opt.stop_reason is None:
        previous = np.array([c.x for c in opt.chains])
        x = opt.ask()
        assert np.all((x >= 0.0) & (x <= 1.0))
        if opt.generation in (1, 2):
            first_moves.append(np.linalg.norm(x - previous, axis=1))
        opt.tell(np.sum((x - 0.4) ** 2, axis=1))
    assert np.mean(first_moves) > 0.3


def test_temperature_is_exponential_in_iterations_without_reannealing():
    opt = SimulatedAnnealing(6, 0, chains=2, reanneal_interval=10**9)
    for _ in range(31):  # start points plus 30 iterations
        opt.tell(np.sum(opt.ask() ** 2, axis=1))
    np.testing.assert_allclose(opt.temperature(1), np.full(6, 100.0 * 0.95**30))


def test_reanneal_formula():
    """k_i = ln((T0/T_i) max(s)/s_i) with T_i = T0 0.95^k_i."""
    k = np.array([100.0, 100.0, 100.0])
    new = reanneal_parameters(k, 0.95, np.array([2.0, 0.2, 0.0]))
    t0, t = 100.0, 100.0 * 0.95**100
    expected = [math.log(t0 / t), math.log(t0 / t * 10.0), math.log(t0 / t * 1e12)]
    np.testing.assert_allclose(new, expected, rtol=1e-9)


def test_sensitivity_from_linear_fit_skips_inf_and_underdetermined():
    rng = np.random.default_rng(0)
    x = rng.random((20, 3))
    f = 3.0 * x[:, 0] - 2.0 * x[:, 1] + 1.0
    np.testing.assert_allclose(estimate_sensitivity(x, f), [3.0, 2.0, 0.0], atol=1e-9)
    f[:17] = np.inf
    assert estimate_sensitivity(x, f) is None
    assert estimate_sensitivity(x, np.ones(20)) is None


def test_reannealing_reheats_the_chain():
    opt = SimulatedAnnealing(6, 0, chains=1, function_tolerance=0.0, budget=3000)
    hottest = []
    while opt.stop_reason is None:
        x = opt.ask()
        opt.tell(1000.0 * np.sum((x - 0.4) ** 2, axis=1))
        hottest.append(opt.temperature(0).max())
    drops = np.diff(hottest)
    assert np.sum(drops > 0) >= 2  # reannealings raised the temperature
    assert max(hottest[200:]) > 1.0


def test_chains_split_budget_and_ask_one_point_each():
    opt = SimulatedAnnealing(6, 0, budget=1003, function_tolerance=0.0)
    assert [c.share for c in opt.chains] == [251, 251, 251, 250]
    sizes = []
    while opt.stop_reason is None:
        x = opt.ask()
        sizes.append(len(x))
        opt.tell(np.sum(x**2, axis=1))
    assert sizes[:250] == [4] * 250 and sizes[250:] == [3]
    assert opt.evaluations == 1003
    assert opt.stop_reason == "all 4 chains stopped: 4 by evaluation budget share"


def test_stall_and_iteration_limit_stop_each_chain():
    flat = SimulatedAnnealing(6, 0, chains=3)
    while flat.stop_reason is None:
        flat.tell(np.ones(len(flat.ask())))
    assert flat.evaluations == 3 * (1 + 150)
    assert flat.stop_reason == "all 3 chains stopped: 3 by stall"
    capped = SimulatedAnnealing(6, 0, chains=2, max_iterations=300, function_tolerance=0.0)
    while capped.stop_reason is None:
        capped.tell(np.ones(len(capped.ask())))
    assert capped.evaluations == 2 * 301


@pytest.mark.filterwarnings("error")
def test_infeasible_trials_are_never_accepted_from_a_feasible_point():
    opt = SimulatedAnnealing(6, 0, budget=2000, function_tolerance=0.0)
    while opt.stop_reason is None:
        x = opt.ask()
        f = np.sum(x**2, axis=1)
        f[x[:, 0] > 0.5] = np.inf
        opt.tell(f)
        assert all(np.isfinite(c.f) or c.x[0] > 0.5 for c in opt.chains)
    assert all(np.isfinite(c.f) for c in opt.chains)
