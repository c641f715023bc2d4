"""CMA-ES adapter: seeding, isolation from numpy's global generator, pycma settings."""

from __future__ import annotations

import numpy as np

from twin_cosim.optimize.algorithms.cmaes import CMAES, pycma_seed


def sphere(x):
    return np.sum((x - 0.3) ** 2, axis=1)


def asks(opt, n):
    out = []
    for _ in range(n):
        x = opt.ask()
        out.append(x)
        opt.tell(sphere(x))
    return out


def test_seed_zero_is_not_pycma_time_seed():
    assert pycma_seed(0) != 0
    assert CMAES(6, 0).es.opts["seed"] == pycma_seed(0)


def test_interleaved_instances_and_global_rng_use_do_not_interfere():
    solo = asks(CMAES(6, 5), 10)
    a, b = CMAES(6, 5), CMAES(6, 5)
    for i in range(10):
        np.random.seed(i)  # noqa: NPY002 (someone else using the global generator)
        before = np.random.get_state()[1].copy()  # noqa: NPY002
        xa = a.ask()
        xb = b.ask()
        np.testing.assert_array_equal(np.random.get_state()[1], before)  # noqa: NPY002
        np.testing.assert_array_equal(xa, solo[i])
        np.testing.assert_array_equal(xb, solo[i])
        a.tell(sphere(xa))
        b.tell(sphere(xb))


def test_popsize_and_sigma0_are_passed_to_pycma():
    opt = CMAES(6, 0, popsize=12, sigma0=0.1)
    assert len(opt.ask()) == 12
    assert opt.es.sigma0 == 0.1


def test_pycma_termination_sets_stop_reason():
    opt = CMAES(3, 0)
    while opt.stop_reason is None:
        opt.tell(np.sum((opt.ask() - 0.3) ** 2, axis=1))
    assert opt.stop_reason.startswith("pycma: tol")
    assert opt.best[1] < 1e-10


def test_an_injected_start_is_evaluated_and_never_lost():
    """Refining a start that is already the optimum: with ``inject_start`` the first generation
    holds the start and the best stays there; without it the start is only the samples' mean."""
    start = np.full(6, 0.3)
    refined = CMAES(6, 2, start, inject_start=True, sigma0=0.3)
    first = refined.ask()
    assert np.array_equal(first[0], start)
    refined.tell(sphere(first))
    asks(refined, 3)
    assert refined.best[1] == 0.0
    plain = CMAES(6, 2, start, sigma0=0.3)
    assert not np.any(np.all(plain.ask() == start, axis=1))


def test_a_start_near_the_bounds_is_injected_as_it_is():
    """pycma's bound transform bends values near 0 and 1; the injected start is not bent."""
    start = np.array([0.01, 0.5, 0.999, 0.0, 1.0, 0.3])
    assert np.allclose(CMAES(6, 4, start, inject_start=True).ask()[0], start, atol=1e-12)
