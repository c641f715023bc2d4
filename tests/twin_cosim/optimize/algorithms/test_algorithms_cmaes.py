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
