"""Candidates scored on a Dask distributed cluster (the ``[dask]`` extra).

A :class:`ObjectivePlugin` (it holds only paths and numbers, so it pickles) builds the plant once
per Dask worker in ``setup``; each task resets that plant and runs one candidate.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from distributed import Client, WorkerPlugin, get_worker
from distributed import as_completed as dask_completed

from twin_cosim.optimize.evaluators import Result
from twin_cosim.optimize.objective import Objective, ObjectiveSpec

PLUGIN_NAME = "twin-objective"


class ObjectivePlugin(WorkerPlugin):
    """Builds the worker's objective once, frees it when the worker closes."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.spec = spec
        self.objective: Objective | None = None

    def setup(self, worker) -> None:
        self.objective = self.spec.build()

    def teardown(self, worker) -> None:
        if self.objective is not None:
            self.objective.close()


def _evaluate_on_worker(x: np.ndarray) -> Result:
    return get_worker().plugins[PLUGIN_NAME].objective(x)


class DaskEvaluator:
    """Evaluations on the cluster whose scheduler listens at ``scheduler`` (tcp://host:8786).

    Use workers with one thread each (``dask worker --nthreads 1``): one FMU instance per worker.
    """

    def __init__(self, spec: ObjectiveSpec, scheduler: str) -> None:
        self.client = Client(scheduler)
        self.client.register_plugin(ObjectivePlugin(spec), name=PLUGIN_NAME)
        self.workers = max(1, len(self.client.scheduler_info()["workers"]))

    def imap(self, candidates: np.ndarray) -> Iterator[tuple[int, Result]]:
        """Yield (row index, result) in order of completion."""
        futures = self.client.map(_evaluate_on_worker, list(candidates), pure=False)
        index = {future.key: i for i, future in enumerate(futures)}
        for future in dask_completed(futures):
            yield index[future.key], future.result()

    def close(self) -> None:
        """Disconnect from the scheduler."""
        self.client.close()
