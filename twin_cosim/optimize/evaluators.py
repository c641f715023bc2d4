"""Evaluators of candidates: serially, on a local process pool (:mod:`twin_cosim.workers`), or on
Dask (:mod:`twin_cosim.optimize.dask_evaluator`, needs the ``[dask]`` extra).

Every worker builds one :class:`~twin_cosim.optimize.objective.Objective` (instantiates the FMU
once, from its extraction in the per-user cache) and resets the plant for every run. Results
stream back as they complete, so a campaign can log each one at once; the order of completion
never changes a result, so every evaluator gives the same campaign for the same seed. An
evaluator offers :class:`~twin_cosim.optimize.evaluator_protocol.Evaluator`.
"""

from __future__ import annotations

from twin_cosim.optimize.evaluator_protocol import Evaluator
from twin_cosim.optimize.worker_specs import ObjectiveSpec
from twin_cosim.workers import BoundPool, ProcessPool, SerialPool


def make_evaluator(
    spec: ObjectiveSpec,
    pool: SerialPool | ProcessPool,
    scheduler: str | None,
    scheduler_timeout: float | None = None,
) -> Evaluator:
    """Dask when a scheduler is given, else the local pool's workers (in this process for a
    :class:`~twin_cosim.workers.SerialPool`); closing the evaluator leaves the pool open.

    ``scheduler_timeout`` (s) bounds the wait for the scheduler and for a first worker.
    """
    if scheduler:  # Dask is an optional extra: imported only when asked for
        from twin_cosim.optimize.dask_evaluator import DaskEvaluator

        return DaskEvaluator(spec, scheduler, scheduler_timeout)
    return BoundPool(pool, spec)
