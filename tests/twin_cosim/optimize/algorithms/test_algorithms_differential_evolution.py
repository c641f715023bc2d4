"""Differential evolution adapter: batches per generation and clean thread shutdown."""

from __future__ import annotations

import gc
import threading

import numpy as np
import pytest

from twin_cosim.optimize.algorithms import differential_evolution as de_module
from twin_cosim.optimize.algorithms.differential_evolution import DifferentialEvolution


def sphere(x):
    return np.sum((x - 0.3) ** 2, axis=1)


def scipy_threads():
    return [t for t in threading.enumerate() if t.name.startswith("scipy-de")]


@pytest.fixture(autouse=True)
def no_lingering_threads():
    yield
    gc.collect()
    assert scipy_threads() == []


def test_one_batch_per_population():
    opt = DifferentialEvolution(6, 0)
    assert opt.population_size == 90
    sizes = []
    for _ in range(3):
        x = opt.ask()
        sizes.append(len(x))
        opt.tell(sphere(x))
    assert sizes == [90, 90, 90]
    opt.close()
    assert DifferentialEvolution(2, 0, popsize=2).population_size == 5


def test_thread_lifecycle_close_mid_run():
    opt = DifferentialEvolution(6, 0)
    assert not opt.thread_alive  # started lazily
    opt.tell(sphere(opt.ask()))
    assert opt.thread_alive
    opt.ask()  # close with a batch outstanding
    opt.close()
    assert not opt.thread_alive
    assert opt.stop_reason == "closed"
    opt.close()  # idempotent


def test_thread_exits_when_budget_is_spent():
    opt = DifferentialEvolution(6, 0, budget=200)
    while opt.stop_reason is None:
        opt.tell(sphere(opt.ask()))
    assert opt.evaluations == 200
    assert not opt.thread_alive


def test_thread_exits_when_scipy_converges():
    opt = DifferentialEvolution(6, 0, tol=10.0)
    while opt.stop_reason is None:
        opt.tell(sphere(opt.ask()))
    assert opt.stop_reason.startswith("scipy: Optimization terminated successfully")
    assert opt.evaluations < opt.budget
    assert not opt.thread_alive


def test_thread_exits_when_optimizer_is_garbage_collected():
    opt = DifferentialEvolution(6, 0)
    opt.ask()
    assert len(scipy_threads()) == 1
    del opt
    gc.collect()
    assert scipy_threads() == []


def test_scipy_error_is_raised_in_caller_and_thread_exits(monkeypatch):
    def broken(*args, **kwargs):
        raise ValueError("boom")

    monkeypatch.setattr(de_module, "differential_evolution", broken)
    opt = DifferentialEvolution(6, 0)
    with pytest.raises(RuntimeError, match="differential_evolution failed") as info:
        opt.ask()
    assert isinstance(info.value.__cause__, ValueError)
    assert not opt.thread_alive
