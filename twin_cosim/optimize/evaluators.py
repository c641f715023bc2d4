"""Evaluators of candidates: serially, on a local process pool (:mod:`twin_cosim.workers`), or on a
Dask distributed cluster (the ``[dask]`` extra), all behind one protocol, :class:`Evaluator`.

Every worker builds its problem's objective (:class:`ProblemObjective`) once from a picklable
recipe (``recipe.build()``: one plant instance per worker) and resets the plant for every run;
the same workers run the reference of each case first (:class:`ReferenceRuns`). Results
(:func:`evaluation_result`) stream back as they complete, so a campaign can log each one at
once; the order of completion never changes a result, so every evaluator gives the same
campaign for the same seed.

On Dask, a worker plugin (:func:`objective_plugin`, holding only the recipe, so it pickles)
gives every thread of every Dask worker its own objective, built on the thread's first task (an
FMU instance is never shared between threads); each task resets that plant and runs one
candidate. Any worker layout is correct (``--nthreads 1`` uses the least memory). A closing
worker tears its plugin down while tasks may still run: teardown waits for each plant's running
task before freeing it, and a task that starts afterwards is rescheduled on another worker.
Connecting is bounded: a scheduler that does not answer, or has no worker within the wait, is a
:class:`SchedulerError` naming ``--scheduler``; so is a scheduler lost in the middle of a run.
Dask is imported only when a scheduler is given.
"""

from __future__ import annotations

import functools
import logging
import queue
import threading
from collections.abc import Iterable, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from twin_cosim.workers import (
    BoundPool,
    ProcessPool,
    SerialPool,
    WorkerFactory,
    deferred_signals,
    tasks_to_give,
    wait_interruptibly,
)

if TYPE_CHECKING:
    import numpy as np
    from distributed import Client, Future, WorkerPlugin

    from twin_cosim.optimize.early_stop import EvaluationTask
    from twin_cosim.workers import Worker

LOG = logging.getLogger(__name__)
Result = dict[str, Any]
PLUGIN_NAME = "twin-objective"
CONNECT_TIMEOUT_S = 10.0  # wait for the scheduler to answer
WORKERS_TIMEOUT_S = 60.0  # wait for a first worker to join


class SchedulerError(ValueError):
    """The Dask scheduler cannot be reached, has no workers, or was lost mid-run."""


class Evaluator(Protocol):
    """Scores tasks on ``workers`` workers, each holding its own plant.

    Attributes
    ----------
    workers : int
        Workers scoring tasks at once.
    ahead : int
        Tasks given out beyond one per worker by a campaign that gives them one at a time
        (early stopping): a worker that finishes finds its next task waiting.
    """

    workers: int
    ahead: int

    def imap(
        self, tasks: Iterable[Any], in_flight: int | None = None
    ) -> Iterator[tuple[int, Result]]:
        """Yield (task index, result) in order of completion, with at most ``in_flight`` tasks
        given out at a time (None: all at once); the next task is taken from ``tasks`` once
        the consumer asks for the next result."""
        ...

    def close(self) -> None:
        """Free the workers."""
        ...


class ProblemObjective(Protocol):
    """What a worker builds from a problem's recipe
    (:meth:`~twin_cosim.optimize.driver.Problem.objective`): its plants, loaded once and reset
    for every run."""

    def __call__(self, task: EvaluationTask | np.ndarray) -> dict[str, Any]:
        """The result of a candidate (physical units), or of a task: :meth:`evaluate` with the
        task's cutoff, lowered by this worker's own complete evaluations of the task's
        generation (:class:`~twin_cosim.optimize.early_stop.OwnEvaluations`)."""
        ...

    def evaluate(self, x: np.ndarray, cutoff: float) -> dict[str, Any]:
        """The result (:func:`evaluation_result`) of candidate
        ``x``; once its fitness is certain to exceed ``cutoff`` (um) it may stop, with status
        ``stopped`` and a lower bound above the cutoff as its fitness."""
        ...

    def reference_of(self, index: int) -> dict[str, Any]:
        """The values of case ``index`` run with the problem's own sets."""
        ...

    def record(self, x: np.ndarray | None, index: int = 0) -> Any:
        """The record of case ``index`` run with candidate ``x`` (None: the own sets), for
        figures."""
        ...

    def close(self) -> None:
        """Free the plants."""
        ...


def evaluation_result(
    fitness: float, status: str, reason: str, metrics: dict[str, Any] | None, steps: int
) -> dict[str, Any]:
    """What a worker answers for a candidate (the :data:`Result` an evaluator streams back): its
    fitness (um), status (``ok``, ``violation``, ``stopped``, ``unstable``, ``failed``), the
    reason, the metrics of its worst case and the speed-loop steps simulated."""
    return {
        "fitness": float(fitness),
        "status": status,
        "reason": reason,
        "metrics": metrics,
        "steps": steps,
    }


def make_evaluator(
    recipe: WorkerFactory,
    pool: SerialPool | ProcessPool,
    scheduler: str | None,
    scheduler_timeout: float | None = None,
) -> Evaluator:
    """Dask when a scheduler is given, else the local pool's workers (in this process for a
    :class:`~twin_cosim.workers.SerialPool`); closing the evaluator leaves the pool open.

    ``recipe`` builds the objective on each worker; ``scheduler_timeout`` (s) bounds the wait
    for the scheduler and for a first worker.
    """
    if scheduler:
        return DaskEvaluator(recipe, scheduler, scheduler_timeout)
    return BoundPool(pool, recipe)


@dataclass(frozen=True)
class ReferenceRuns:
    """The recipe of a worker answering the reference run of a case (its index) of the
    objective that ``objective`` builds (a campaign's cases are run on its evaluators' workers
    before its candidates, :meth:`twin_cosim.optimize.driver.Problem.objective`)."""

    objective: WorkerFactory

    def build(self) -> _CaseReferences:
        """The worker, in the process that runs it."""
        return _CaseReferences(self.objective.build())


class _CaseReferences:
    """A worker answering ``objective.reference_of(case)``."""

    def __init__(self, objective: ProblemObjective) -> None:
        self.objective = objective

    def __call__(self, index: int) -> dict[str, Any]:
        return self.objective.reference_of(index)

    def close(self) -> None:
        self.objective.close()


class ThreadObjectives:
    """One objective per thread of a Dask worker, built on the thread's first task, all freed
    when the worker closes: what the worker plugin (:func:`objective_plugin`) does."""

    def __init__(self, recipe: WorkerFactory) -> None:
        self.recipe = recipe

    def setup(self, worker: Any = None) -> None:
        """Start without objectives (a worker starts the plugin)."""
        self._local = threading.local()
        self._lock = threading.Lock()
        self._built: list[tuple[Worker, threading.Lock]] = []
        self._closed = False

    def evaluate(self, task: Any) -> Result:
        """Score ``task`` on the calling thread's objective (built on the thread's first task);
        once torn down, Dask reschedules the task on another worker."""
        slot = getattr(self._local, "slot", None)
        if slot is None:
            with self._lock:
                if self._closed:
                    _reschedule()
                slot = (self.recipe.build(), threading.Lock())
                self._built.append(slot)
            self._local.slot = slot
        objective, busy = slot
        with busy:
            if self._closed:
                _reschedule()
            return objective(task)

    def teardown(self, worker: Any = None) -> None:
        """Free every objective, each once its running task ended (a worker closes)."""
        with self._lock:
            self._closed = True
            built, self._built = self._built, []
        for objective, busy in built:
            with busy:  # a running task ends first
                objective.close()


def _reschedule() -> None:
    from distributed import Reschedule

    raise Reschedule()


def objective_plugin(recipe: WorkerFactory) -> WorkerPlugin:
    """The Dask worker plugin of :class:`ThreadObjectives` for ``recipe`` (registered as
    :data:`PLUGIN_NAME`)."""
    return _plugin_type()(recipe)


@functools.cache
def _plugin_type() -> type:
    """Dask's worker plugin type of :class:`ThreadObjectives`, made on first use (Dask is an
    optional extra, imported only when a scheduler is given)."""
    from distributed import WorkerPlugin

    class ObjectivePlugin(ThreadObjectives, WorkerPlugin):
        def __reduce__(self) -> tuple[Any, ...]:  # pickled as its recipe, rebuilt by the worker
            return objective_plugin, (self.recipe,)

    return ObjectivePlugin


def _evaluate_on_worker(task: Any) -> Result:
    from distributed import get_worker

    return get_worker().plugins[PLUGIN_NAME].evaluate(task)


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
    from distributed import Client

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

    def __init__(self, recipe: WorkerFactory, scheduler: str, timeout: float | None = None) -> None:
        self.address = scheduler
        self.client = connect(scheduler, timeout)
        try:
            self.client.register_plugin(objective_plugin(recipe), name=PLUGIN_NAME)
            self.workers = max(1, len(self.client.scheduler_info()["workers"]))
        except BaseException:
            self.client.close()
            raise
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
        from distributed.comm.core import CommClosedError

        lost = (CommClosedError, CancelledError, OSError, TimeoutError)  # the scheduler went away
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
        except lost as exc:
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
