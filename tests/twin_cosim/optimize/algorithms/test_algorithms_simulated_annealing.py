"""Simulated annealing: bound redraw, cooling, reannealing, chains and stopping rules."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.optimize.algorithms.annealing import (
    SimulatedAnnealing,
    estimate_sensitivity,
    reanneal_parameters,
    redraw_out_of_bounds,
)


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
