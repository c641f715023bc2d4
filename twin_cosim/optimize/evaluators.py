"""Evaluators: score a batch of candidates serially, on a local process pool, or on Dask
(:mod:`twin_cosim.optimize.dask_evaluator`, needs the ``[dask]`` extra).

Each worker builds one :class:`~twin_cosim.optimize.objective.Objective` (extracts and
instantiates the FMU once) and resets the plant for every run. Results stream back as they
complete, so a campaign can log each one at once; the order of completion never changes a
result, so every evaluator gives the same campaign for the same seed.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

import numpy as np

from twin_cosim.optimize.objective import Objective, ObjectiveSpec

Result = dict[str, Any]

_WORKER_OBJECTIVE: Objective | None = None


class SerialEvaluator:
    """Evaluates candidates one after the other in this process."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.objective = Objective(spec)
        self.workers = 1

    def imap(self, candidates: np.ndarray) -> Iterator[tuple[int, Result]]:
        """Yield (row index, result) for each row of ``candidates``."""
        for index, x in enumerate(candidates):
            yield index, self.objective(x)

    def close(self) -> None:
        """Free the plant."""
        self.objective.close()


def _init_worker(spec: ObjectiveSpec) -> None:
    global _WORKER_OBJECTIVE
    _WORKER_OBJECTIVE = Objective(spec)


def _evaluate_in_worker(x: np.ndarray) -> Result:
    assert _WORKER_OBJECTIVE is not None, "worker not initialised"
    return _WORKER_OBJECTIVE(x)


class PoolEvaluator:
    """A local pool of spawned processes, one plant instance each.

    Parameters
    ----------
    spec
        The objective each worker builds.
    workers
        Number of processes; all cores when None.
    """

    def __init__(self, spec: ObjectiveSpec, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self.executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(spec,),
        )

    def imap(self, candidates: np.ndarray) -> Iterator[tuple[int, Result]]:
        """Yield (row index, result) in order of completion."""
        futures = {
            self.executor.submit(_evaluate_in_worker, x): i for i, x in enumerate(candidates)
        }
        for future in as_completed(futures):
            yield futures[future], future.result()

    def close(self) -> None:
        """Shut the pool down."""
        self.executor.shutdown(cancel_futures=True)


def make_evaluator(spec: ObjectiveSpec, workers: int | None, scheduler: str | None):
    """Dask when a scheduler is given, serial for one worker, else a local process pool."""
    if scheduler:
        from twin_cosim.optimize.dask_evaluator import DaskEvaluator

        return DaskEvaluator(spec, scheduler)
    if workers == 1:
        return SerialEvaluator(spec)
    return PoolEvaluator(spec, workers)
