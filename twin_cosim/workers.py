"""Worker pools for FMU work: each worker builds its own plant once and reuses it for every task.

A *factory* is a picklable object (paths and numbers only) with a ``build()`` method returning the
worker: a callable ``worker(task) -> result`` with a ``close()`` method. In a process pool every
process calls ``build()`` once (spawned processes: an FMU is never instantiated in a parent that
then forks); tasks then run on that worker and results stream back as they complete.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Protocol


class Worker(Protocol):
    """Does one task at a time on resources it holds (a plant)."""

    def __call__(self, task: Any) -> Any: ...

    def close(self) -> None: ...


class WorkerFactory(Protocol):
    """Picklable recipe of a worker."""

    def build(self) -> Worker: ...


class SerialPool:
    """Runs the tasks one after the other in this process, on one worker."""

    def __init__(self, factory: WorkerFactory) -> None:
        self.worker = factory.build()
        self.workers = 1

    def imap(self, tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) for each task, in order."""
        for index, task in enumerate(tasks):
            yield index, self.worker(task)

    def close(self) -> None:
        """Free the worker's resources."""
        self.worker.close()


_PROCESS_WORKER: Worker | None = None


def _build_in_process(factory: WorkerFactory) -> None:
    global _PROCESS_WORKER
    _PROCESS_WORKER = factory.build()


def _run_in_process(task: Any) -> Any:
    if _PROCESS_WORKER is None:
        raise RuntimeError("worker process was not initialised")
    return _PROCESS_WORKER(task)


class ProcessPool:
    """A local pool of spawned processes, one worker (one plant instance) each.

    Parameters
    ----------
    factory
        The recipe every process builds its worker from.
    workers
        Number of processes; all cores when None.
    """

    def __init__(self, factory: WorkerFactory, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self.executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_build_in_process,
            initargs=(factory,),
        )

    def imap(self, tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) in order of completion."""
        futures = {self.executor.submit(_run_in_process, task): i for i, task in enumerate(tasks)}
        for future in as_completed(futures):
            yield futures[future], future.result()

    def close(self) -> None:
        """Shut the pool down."""
        self.executor.shutdown(cancel_futures=True)


def make_pool(factory: WorkerFactory, workers: int | None):
    """Serial in this process for one worker, else a process pool."""
    return SerialPool(factory) if workers == 1 else ProcessPool(factory, workers)
