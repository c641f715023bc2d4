"""Candidates scored on a Dask distributed cluster (the ``[dask]`` extra).

A :class:`ObjectivePlugin` (it holds only resolved values, so it pickles) gives every thread of
every Dask worker its own objective, built on the thread's first task (one plant instance per
thread: an FMU instance is never shared between threads); each task resets that plant and runs one
candidate. Any worker layout is correct (``--nthreads 1`` uses the least memory). A closing worker
tears its plugin down while tasks may still run: teardown waits for each plant's running task
before freeing it, and a task that starts afterwards is rescheduled on another worker.

Connecting is bounded: a scheduler that does not answer, or has no worker within the wait, is a
:class:`SchedulerError` naming ``--scheduler``; so is a scheduler lost in the middle of a run.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Iterable, Iterator
from concurrent.futures import CancelledError
from typing import Any

import numpy as np
from distributed import Client, Future, Reschedule, WorkerPlugin, get_worker
from distributed.comm.core import CommClosedError

from twin_cosim.interrupts import deferred_signals, wait_interruptibly
from twin_cosim.optimize.evaluator_protocol import Result, SchedulerError
from twin_cosim.optimize.objective import Objective, ObjectiveSpec
from twin_cosim.workers import tasks_to_give

LOG = logging.getLogger(__name__)
PLUGIN_NAME = "twin-objective"
CONNECT_TIMEOUT_S = 10.0  # wait for the scheduler to answer
WORKERS_TIMEOUT_S = 60.0  # wait for a first worker to join
LOST = (CommClosedError, CancelledError, OSError, TimeoutError)  # the scheduler went away


class ObjectivePlugin(WorkerPlugin):
    """One objective per worker thread, built on first use, all freed when the worker closes."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.spec = spec

    def setup(self, worker) -> None:
        self._local = threading.local()
        self._lock = threading.Lock()
        self._built: list[tuple[Objective, threading.Lock]] = []
        self._closed = False

    def evaluate(self, x: np.ndarray) -> Result:
        """Score ``x`` on the calling thread's objective (built on the thread's first task)."""
        slot = getattr(self._local, "slot", None)
        if slot is None:
            with self._lock:
                if self._closed:
                    raise Reschedule()
                slot = (self.spec.build(), threading.Lock())
                self._built.append(slot)
            self._local.slot = slot
        objective, busy = slot
        with busy:
            if self._closed:
                raise Reschedule()
            return objective(x)

    def teardown(self, worker) -> None:
        with self._lock:
            self._closed = True
            built, self._built = self._built, []
        for objective, busy in built:
            with busy:  # a running task ends first
                objective.close()


def _evaluate_on_worker(x: np.ndarray) -> Result:
    return get_worker().plugins[PLUGIN_NAME].evaluate(x)


def connect(address: str, timeout: float | None = None) -> Client:
    """A client of the scheduler at ``address`` that has at least one worker.

    Parameters
    ----------
    address
        Scheduler address, e.g. tcp://host:8786.
    timeout
        Seconds to wait for the scheduler, then again for a first worker (defaults
        :data:`CONNECT_TIMEOUT_S` and :data:`WORKERS_TIMEOUT_S`).

    Raises
    ------
    SchedulerError
        Naming ``--scheduler`` when nothing answers or no worker joins in time.
    """
    connect_timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    workers_timeout = WORKERS_TIMEOUT_S if timeout is None else timeout
    try:
        client = Client(address, timeout=connect_timeout)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise SchedulerError(
            f"--scheduler {address}: no Dask scheduler answered within {connect_timeout:g} s "
            f"({exc})"
        ) from None
    if not client.scheduler_info()["workers"]:
        LOG.warning("--scheduler %s: no worker yet; waiting up to %g s", address, workers_timeout)
        try:
            client.wait_for_workers(1, timeout=workers_timeout)
        except TimeoutError:
            client.close()
            raise SchedulerError(
                f"--scheduler {address}: the scheduler has no worker (none joined within "
                f"{workers_timeout:g} s); start one with: dask worker {address}"
            ) from None
    return client


def check_scheduler(address: str, timeout: float | None = None) -> None:
    """Raise :class:`SchedulerError` unless ``address`` answers and has a worker."""
    connect(address, timeout).close()


class DaskEvaluator:
    """Evaluations on the cluster whose scheduler listens at ``scheduler`` (tcp://host:8786)."""

    def __init__(self, spec: ObjectiveSpec, scheduler: str, timeout: float | None = None) -> None:
        self.address = scheduler
        self.client = connect(scheduler, timeout)
        self.client.register_plugin(ObjectivePlugin(spec), name=PLUGIN_NAME)
        self.workers = max(1, len(self.client.scheduler_info()["workers"]))
        # One task per worker, as measured so far (a cluster was not timed with more)
        self.ahead = 0

    def imap(
        self, tasks: Iterable[Any], in_flight: int | None = None
    ) -> Iterator[tuple[int, Result]]:
        """Yield (task index, result) in order of completion, with at most ``in_flight`` tasks
        on the cluster at a time (None: all at once).

        Raises
        ------
        SchedulerError
            When the connection to the scheduler is lost.
        """
        finished: queue.Queue[Future] = queue.Queue()
        pending = enumerate(tasks)
        index: dict[str, int] = {}

        def give_out() -> None:
            with deferred_signals():  # Ctrl-C never lands inside the client's machinery
                for i, task in tasks_to_give(pending, len(index), in_flight):
                    future = self.client.submit(_evaluate_on_worker, task, pure=False)
                    index[future.key] = i
                    future.add_done_callback(finished.put)

        try:
            give_out()
            while index:
                future = wait_interruptibly(lambda timeout_s: _next_within(finished, timeout_s))
                yield index.pop(future.key), future.result()
                give_out()
        except LOST as exc:
            first_line = (str(exc).splitlines() or [""])[0]
            raise SchedulerError(
                f"--scheduler {self.address}: lost the scheduler mid-run ({type(exc).__name__}: "
                f"{first_line})"
            ) from None

    def close(self) -> None:
        """Disconnect from the scheduler (its tasks of this client are released); a Ctrl-C or
        SIGTERM meanwhile is raised once it is done."""
        with deferred_signals():
            self.client.close()


def _next_within(finished: queue.Queue[Future], timeout_s: float) -> Future | None:
    """The next finished future within ``timeout_s`` (s); None: none yet."""
    try:
        return finished.get(timeout=timeout_s)
    except queue.Empty:
        return None
