"""Ctrl-C and SIGTERM in a process that drives workers: raised only where it is safe.

Python runs a signal's handler between any two bytecodes of the main thread. Raised inside the
machinery of a process pool or a Dask client (a future's lock taken, a queue half fed, a pool
half shut down), the KeyboardInterrupt leaves that machinery locked, and the shutdown that
follows waits for ever (issue 18). So:

- :func:`deferred_signals`: within the block, SIGINT and SIGTERM are recorded, not raised; at
  its end the first one recorded is sent again to the handlers the block restored, which raise
  it there, outside the machinery;
- :func:`wait_interruptibly`: a wait for workers made of short waits inside such a block, so
  that a signal meanwhile ends the wait at once and is raised between two short waits;
- :func:`stop_handlers`: the handlers of a command: a Ctrl-C (KeyboardInterrupt) or SIGTERM
  (:class:`Terminated`) is raised, and absorbed while one is being handled (``timeout -s INT``
  signals the command, then its group: two signals, one wish); one that Python dropped (raised
  in a weakref callback) is raised again at the next wait for workers.

Worker pools for FMU work: each worker builds its own plant once and reuses it for every task.

A *factory* is a picklable object (plain values: paths, numbers, resolved scenarios) with a
``build()`` method returning the worker: a callable ``worker(task) -> result`` with a ``close()``
method. In a process pool every process calls ``build()`` once (spawned processes: an FMU is never
instantiated in a parent that then forks); tasks then run on that worker and results stream back
as they complete.

A pool starts its processes at once, before it has work: each runs ``prepare`` (e.g. imports the
co-simulation and readies the compiled loop) while the parent prepares its tasks. One pool serves
several factories in turn (``imap(tasks, factory)``; :class:`BoundPool` is a pool seen as the
evaluator of one factory): a process builds the new worker at its first task of that factory and
closes the one before, so a command starts its processes once (``twin compare``: every method's
campaign, the reference runs and the runs of the tables and figures on one pool). A process pool
can also give tasks out ahead (:meth:`LocalPool.start`), their results taken later
(:class:`Started`), so that its workers run them while the parent does work of its own (a
diagnosis: the nominal twin's calibration directions while it finds the noise).

Nothing outlives a pool. Every pool has a private temp folder (``twin-pool-<parent pid>-*``) that
holds its workers' temporary files and its stored factories, and that ``close()`` removes (FMUs
are extracted into the per-user cache, :func:`twin_cosim.plant.extracted_fmu`). A pool closed
before it was given a task terminates its processes instead of awaiting their preparation; one
closed while tasks still run (Ctrl-C, an error) kills them: their results are not wanted and a
long run would delay the end. A worker ignores Ctrl-C from the moment it starts (it is started
with SIGINT blocked, and ignores it before unblocking it, so a Ctrl-C while it still imports
prints no traceback; its parent handles Ctrl-C and shuts the pool down), frees its plant when it
exits, and dies with its parent: a watchdog thread polls the parent's pid, so after ``kill -9``
of the parent every worker removes the pool's folder and exits (the multiprocessing resource
tracker then ends too). A command of the ``twin`` CLI keeps all its temporary files in one such
folder (:func:`command_temp_folder`); one left by a process that could not clean up (``kill -9``
of a serial run) is removed by the next pool or command.

The parent never lets a Ctrl-C or SIGTERM land inside the executor's machinery: submitting,
waiting and shutting down run with those signals deferred (:mod:`twin_cosim.workers`), which
are raised between two of those steps instead.

**Scenario runs on a worker pool**: their records, for tables and figures. Light to import: the
parent of a pool builds the tasks and never runs the plant; the plant and the compiled master are
loaded in the workers (:class:`PlantTasks`), which start with :func:`prepare_worker`.
"""

from __future__ import annotations

import abc
import importlib
import multiprocessing
import multiprocessing.util
import os
import pickle
import re
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, Self, TypeVar

if TYPE_CHECKING:
    from collections.abc import Callable

    from twin_cosim.controller import TunedParameters
    from twin_cosim.plant import Plant
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario


T = TypeVar("T")
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
POLL_S = 0.1  # longest wait between two checks for a deferred signal


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled like Ctrl-C, so that every ``finally`` runs."""


class Deferral:
    """The signal recorded while signals were deferred (None: none came)."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def record(self, signum: int, frame: Any) -> None:
        """A signal handler that keeps the first signal for later."""
        if self.signum is None:
            self.signum = signum


@contextmanager
def deferred_signals() -> Iterator[Deferral]:
    """Record SIGINT and SIGTERM in this block; at its end, raise the first one recorded.

    The signal goes again to the handlers restored at the end (a KeyboardInterrupt with
    Python's, nothing where it is ignored). Outside the main thread, where handlers cannot be
    set and signals are never raised, the block changes nothing.
    """
    deferral = Deferral()
    if threading.current_thread() is not threading.main_thread():
        yield deferral
        return
    previous = {signum: signal.signal(signum, deferral.record) for signum in STOP_SIGNALS}
    try:
        yield deferral
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if deferral.signum is not None:
            signal.raise_signal(deferral.signum)  # its handler runs before the next bytecode


def first_done(futures: Iterable[Future], timeout_s: float) -> set[Future] | None:
    """The futures done within ``timeout_s`` (s), at least one; None: none yet."""
    done, _ = wait(futures, timeout=timeout_s, return_when=FIRST_COMPLETED)
    return done or None


def wait_interruptibly(wait_some: Callable[[float], T | None]) -> T:
    """The first answer of ``wait_some(timeout_s)``, called until it answers (not None).

    Signals are deferred during each call, so they never land inside the machinery it waits
    on; one that comes ends the waiting and is raised at most :data:`POLL_S` later.
    """
    while True:
        raise_requested_stop()
        with deferred_signals() as deferral:
            while deferral.signum is None:
                answer = wait_some(POLL_S)
                if answer is not None:
                    return answer


_requested: int | None = None  # the stop signal a command was given (None: none yet)


def _stop(signum: int, frame: Any) -> None:
    """A command's handler: raise the stop, unless one is being handled (a second signal
    during the shutdown the first began)."""
    global _requested
    if isinstance(sys.exc_info()[1], KeyboardInterrupt):
        return
    _requested = signum
    _raise_stop(signum)


def _raise_stop(signum: int) -> None:
    if signum == signal.SIGTERM:
        raise Terminated(f"signal {signum}")
    raise KeyboardInterrupt


def raise_requested_stop() -> None:
    """Raise the stop signal a command was given again, if it was lost.

    Python drops an exception raised where it cannot propagate (a weakref callback, a
    ``__del__``: "Exception ignored in ..."); a Ctrl-C raised there would be lost. Each wait
    for workers (:func:`wait_interruptibly`) calls this, so the command stops there.
    """
    if _requested is not None:
        _raise_stop(_requested)


@contextmanager
def stop_handlers() -> Iterator[None]:
    """In this block a Ctrl-C or SIGTERM raises (KeyboardInterrupt, :class:`Terminated`), except
    while one is being handled, so that a second signal never breaks the shutdown the first
    began; one Python dropped is raised again by :func:`raise_requested_stop`. The handlers
    before are restored at the end."""
    global _requested
    _requested = None
    previous = {signum: signal.signal(signum, _stop) for signum in STOP_SIGNALS}
    previous_hook = sys.unraisablehook

    def drop_quietly(unraisable: Any) -> None:
        """A stop Python dropped is raised again (:func:`raise_requested_stop`): no traceback."""
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):
            previous_hook(unraisable)

    sys.unraisablehook = drop_quietly
    try:
        yield
    finally:
        _requested = None
        sys.unraisablehook = previous_hook
        for signum, handler in previous.items():
            signal.signal(signum, handler)


POOL_PREFIX = "twin-pool-"
PARENT_POLL_S = 0.2  # how often a worker checks that its parent is alive


class Worker(Protocol):
    """Does one task at a time on resources it holds (a plant)."""

    def __call__(self, task: Any) -> Any: ...

    def close(self) -> None: ...


class WorkerFactory(Protocol):
    """Picklable recipe of a worker."""

    def build(self) -> Worker: ...


def pid_alive(pid: int) -> bool:
    """Whether a process with this id runs (perhaps another user's)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_pool_folders() -> None:
    """Remove pool folders in the temp folder whose process is no longer running."""
    for folder in Path(tempfile.gettempdir()).glob(f"{POOL_PREFIX}*"):
        match = re.fullmatch(rf"{POOL_PREFIX}(\d+)-.*", folder.name)
        if match and folder.is_dir() and not pid_alive(int(match.group(1))):
            shutil.rmtree(folder, ignore_errors=True)


def new_pool_folder() -> str:
    """A private temp folder for a pool of this process (stale ones of dead processes removed)."""
    remove_stale_pool_folders()
    return tempfile.mkdtemp(prefix=f"{POOL_PREFIX}{os.getpid()}-")


@contextmanager
def _temp_root(folder: str) -> Iterator[None]:
    """Temporary files of this process (e.g. an extracted FMU) go to ``folder`` meanwhile."""
    before = tempfile.tempdir
    tempfile.tempdir = folder
    try:
        yield
    finally:
        tempfile.tempdir = before


@contextmanager
def command_temp_folder() -> Iterator[str]:
    """All temporary files of this process go to a private folder, removed at the end.

    Pools started meanwhile put theirs inside it. After ``kill -9`` the pool's workers remove it;
    a folder left anyway is removed by the next pool or command (its process is dead).
    """
    folder = new_pool_folder()
    try:
        with _temp_root(folder):
            yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


class LocalPool(abc.ABC):
    """What both local pools offer: tasks streamed through the workers of a factory, and a
    context manager that closes the pool at its end."""

    def imap(
        self,
        tasks: Iterable[Any],
        factory: WorkerFactory | None = None,
        in_flight: int | None = None,
    ) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) on ``factory``'s workers (None: the last factory's), in
        order of completion.

        ``in_flight`` tasks at most are given out at a time (None: all at once); the next task
        is taken from ``tasks`` once a result was yielded and its consumer asks for the next
        one, so a task made then may use every result before it.
        """
        if factory is not None:
            self._use(factory)
        return self._results(tasks, in_flight)

    def start(self, tasks: list[Any], factory: WorkerFactory) -> Started | None:
        """Give ``tasks`` out now on ``factory``'s workers, their results to be taken later
        (:meth:`Started.results`), while this process does other work; None: this pool cannot
        (a serial pool has no worker but this process). ``factory`` becomes the last factory
        (:meth:`imap` without one runs on it)."""
        return None

    @abc.abstractmethod
    def _use(self, factory: WorkerFactory) -> None:
        """Tasks from now on run on ``factory``'s workers."""

    @abc.abstractmethod
    def _results(self, tasks: Iterable[Any], in_flight: int | None) -> Iterator[tuple[int, Any]]:
        """The tasks' (index, result) pairs on the last factory's workers (:meth:`imap`)."""

    @abc.abstractmethod
    def close(self) -> None:
        """Free the workers and remove the pool's temp folder."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


class Started:
    """Tasks given out ahead (:meth:`LocalPool.start`): their results when the caller is ready
    for them, or their cancellation when it finds it does not need them."""

    def __init__(self, tasks: list[Any], futures: list[Future]) -> None:
        self.tasks = tasks
        self.futures = futures

    def results(self) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) in order of completion, waiting as :meth:`LocalPool.imap`
        does (a Ctrl-C or SIGTERM meanwhile is raised between two short waits)."""
        pending = {future: index for index, future in enumerate(self.futures)}
        while pending:
            for future in wait_interruptibly(lambda timeout_s: first_done(pending, timeout_s)):
                yield pending.pop(future), future.result()

    def cancel(self) -> None:
        """Cancel the tasks not begun (those running end, their results unread)."""
        with deferred_signals():
            for future in self.futures:
                future.cancel()


class SerialPool(LocalPool):
    """Runs the tasks one after the other in this process, on one worker at a time.

    Parameters
    ----------
    factory
        The recipe of the first worker (built now); None: the first ``imap`` gives it.
    """

    ahead = 0  # the next task is made once the last result was consumed: none can wait

    def __init__(self, factory: WorkerFactory | None = None) -> None:
        self.folder = new_pool_folder()
        self.workers = 1
        self._factory: WorkerFactory | None = None
        self._worker: Worker | None = None
        if factory is not None:
            try:
                self._use(factory)
            except BaseException:
                shutil.rmtree(self.folder, ignore_errors=True)
                raise

    def _use(self, factory: WorkerFactory) -> None:
        """Close the worker of another factory, build this one's."""
        if factory is self._factory:
            return
        previous, self._worker, self._factory = self._worker, None, None
        if previous is not None:
            previous.close()
        with _temp_root(self.folder):
            self._worker = factory.build()
        self._factory = factory

    def _results(self, tasks: Iterable[Any], in_flight: int | None) -> Iterator[tuple[int, Any]]:
        """Each task's result in turn, on the last factory's worker (``in_flight`` is 1 whatever
        it is given as)."""
        if self._worker is None:
            raise RuntimeError("the pool has no worker yet: give imap a factory")
        for index, task in enumerate(tasks):
            yield index, self._worker(task)

    def close(self) -> None:
        """Free the worker's resources and remove its temp folder."""
        try:
            if self._worker is not None:
                self._worker.close()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


_PROCESS_WORKER: Worker | None = None
# The file of the factory _PROCESS_WORKER was built from; None: the pool's own factory.
_PROCESS_FACTORY: str | None = None


def _close_process_worker(folder: str) -> None:
    """The worker process's normal end (the pool shuts down): free the worker, remove its
    folder, and end at once, without tearing the interpreter down (a third of a second once
    numba is loaded; the pool's close waits for it)."""
    try:
        if _PROCESS_WORKER is not None:
            _PROCESS_WORKER.close()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _watch_parent(parent_pid: int, pool_folder: str) -> None:
    """Exit this worker once its parent is gone (reparented), removing the pool's folder.

    When the pool's folder lies in the parent's command folder (:func:`command_temp_folder`),
    that goes too.
    """
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    shutil.rmtree(pool_folder, ignore_errors=True)
    outer = Path(pool_folder).parent
    if re.fullmatch(rf"{POOL_PREFIX}{parent_pid}-.*", outer.name):
        shutil.rmtree(outer, ignore_errors=True)
    os._exit(1)


def _exit_on_sigterm(folder: str) -> None:
    def handler(signum: int, frame: Any) -> None:
        shutil.rmtree(folder, ignore_errors=True)
        os._exit(128 + signum)

    signal.signal(signal.SIGTERM, handler)


def _build_in_process(
    factory: WorkerFactory | None,
    pool_folder: str,
    parent_pid: int,
    prepare: Callable[[], None] | None,
) -> None:
    global _PROCESS_WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C; a Ctrl-C pending
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # since the start is dropped
    folder = tempfile.mkdtemp(dir=pool_folder)
    tempfile.tempdir = folder
    _exit_on_sigterm(folder)
    threading.Thread(target=_watch_parent, args=(parent_pid, pool_folder), daemon=True).start()
    multiprocessing.util.Finalize(None, _close_process_worker, args=(folder,), exitpriority=10)
    if prepare is not None:
        prepare()
    if factory is not None:
        _PROCESS_WORKER = factory.build()


def _started() -> None:
    """The first task of each process: it starts the process (its preparation runs at once)."""


@contextmanager
def _children_start_blocking_interrupts() -> Iterator[None]:
    """Processes started in this block start with SIGINT blocked (a signal mask survives fork
    and exec); they ignore it once they run their initializer.

    Only this thread blocks SIGINT meanwhile, and its handler stays: a Ctrl-C goes to another
    thread of this process, or waits for the block's end, and is never lost. (Ignoring SIGINT
    here instead, for the children to inherit, would drop a Ctrl-C that another thread, e.g. a
    BLAS thread, receives meanwhile.)
    """
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


def tasks_to_give(
    pending: Iterator[tuple[int, Any]], running: int, in_flight: int | None
) -> Iterator[tuple[int, Any]]:
    """The (index, task) pairs of ``pending`` to give out now, with ``running`` tasks out: until
    ``in_flight`` are out (None: every one left). Each is taken from ``pending`` as it is given
    out, so a task made by a generator may use every result before it."""
    while in_flight is None or running < in_flight:
        taken = next(pending, None)
        if taken is None:
            return
        running += 1
        yield taken


# Environment variables of the BLAS thread count (OpenBLAS, which numpy and SciPy ship, and
# OpenMP builds)
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")


@contextmanager
def _children_with_one_blas_thread() -> Iterator[None]:
    """Processes started in this block use one BLAS thread, unless the user set the count.

    The pool's processes fill the cores, and their linear algebra is small (the fits of a
    diagnosis, a metric): more BLAS threads would only spin beside the other processes. This
    process keeps its own setting (spawned children read the environment as they start).
    """
    added = [name for name in BLAS_THREAD_VARIABLES if name not in os.environ]
    for name in added:
        os.environ[name] = "1"
    try:
        yield
    finally:
        for name in added:
            os.environ.pop(name, None)


def _run_in_process(task: Any, factory_file: str | None) -> Any:
    """Run ``task`` on the worker of the factory stored in ``factory_file`` (None: the pool's
    own), building it first when this process holds another factory's."""
    global _PROCESS_WORKER, _PROCESS_FACTORY
    if factory_file != _PROCESS_FACTORY:
        previous, _PROCESS_WORKER = _PROCESS_WORKER, None
        if previous is not None:
            previous.close()
        factory = pickle.loads(Path(factory_file).read_bytes())
        _PROCESS_WORKER = factory.build()
        _PROCESS_FACTORY = factory_file
    if _PROCESS_WORKER is None:
        raise RuntimeError("worker process was not initialised")
    return _PROCESS_WORKER(task)


class ProcessPool(LocalPool):
    """A local pool of spawned processes, one worker (one plant instance) each.

    The processes start at once; each runs ``prepare`` and builds ``factory``'s worker before
    its first task.

    Parameters
    ----------
    factory
        The recipe every process builds its worker from; None: the first ``imap`` gives it.
    workers
        Number of processes (>= 1); all cores when None.
    prepare
        A picklable function each process calls as it starts (e.g. imports its tasks need).
    """

    # Tasks given out beyond one per worker (a campaign with early stopping): a process finds its
    # next task in the pool's queue, where the round trip of a result through the command (about
    # 0.8 ms on 2 cores) would leave it idle
    ahead = 1

    def __init__(
        self,
        factory: WorkerFactory | None = None,
        workers: int | None = None,
        prepare: Callable[[], None] | None = None,
    ) -> None:
        check_workers(workers)
        self.workers = workers or os.cpu_count() or 1
        self.folder = new_pool_folder()
        self._factory = factory
        self._factory_file: str | None = None
        self._factories = 0  # factories stored so far
        self._used = False  # a task was given
        self._running: set[Future] = set()  # tasks given and not yet answered
        self._given_ahead: list[Future] = []  # tasks given out ahead (:meth:`start`)
        self.executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_build_in_process,
            initargs=(factory, self.folder, os.getpid(), prepare),
        )
        try:
            with (
                deferred_signals(),
                _children_start_blocking_interrupts(),
                _children_with_one_blas_thread(),
            ):
                for _ in range(self.workers):  # each submit starts one process
                    self.executor.submit(_started)
        except BaseException:  # Ctrl-C meanwhile: nothing is left running
            self.close()
            raise

    def _use(self, factory: WorkerFactory) -> None:
        """Tasks from now on run on ``factory``'s workers (stored for the processes to read)."""
        if factory is self._factory:
            return
        self._factories += 1
        path = Path(self.folder) / f"factory-{self._factories}.pickle"
        path.write_bytes(pickle.dumps(factory))
        self._factory, self._factory_file = factory, str(path)

    def start(self, tasks: list[Any], factory: WorkerFactory) -> Started:
        """Give ``tasks`` out now on ``factory``'s workers (:meth:`LocalPool.start`)."""
        self._use(factory)
        self._used = True
        self._forget_done_ahead()
        with deferred_signals():
            futures = []
            for task in tasks:  # each recorded at once: close() kills what a Ctrl-C leaves running
                futures.append(self.executor.submit(_run_in_process, task, self._factory_file))
                self._given_ahead.append(futures[-1])
        return Started(list(tasks), futures)

    def _forget_done_ahead(self) -> None:
        """Drop the tasks given out ahead that are done (each holds its result) from those
        :meth:`close` may have to kill."""
        self._given_ahead = [f for f in self._given_ahead if not f.done()]

    def _results(self, tasks: Iterable[Any], in_flight: int | None) -> Iterator[tuple[int, Any]]:
        """The tasks' results in order of completion, on the last factory's workers."""
        self._used = True
        pending = enumerate(tasks)
        futures: dict[Future, int] = {}
        self._running = set()
        self._forget_done_ahead()

        def give_out() -> None:
            with deferred_signals():
                for index, task in tasks_to_give(pending, len(self._running), in_flight):
                    future = self.executor.submit(_run_in_process, task, self._factory_file)
                    futures[future] = index
                    self._running.add(future)

        give_out()
        while self._running:
            for future in wait_interruptibly(
                lambda timeout_s: first_done(self._running, timeout_s)
            ):
                self._running.discard(future)
                yield futures.pop(future), future.result()
            give_out()

    def close(self) -> None:
        """Shut the pool down (workers free their plants) and remove its temp folder.

        Processes that were given no task yet (an error or Ctrl-C while the parent prepared)
        are terminated rather than awaited: their preparation would delay the end for nothing.
        Processes with tasks still running (Ctrl-C or an error while the parent waited, tasks
        started ahead and not awaited) are killed: their results are not wanted, and a long run
        would delay the end. A Ctrl-C or SIGTERM during the shutdown is raised once it is
        complete.
        """
        with deferred_signals():
            try:
                # the executor offers no public way to its processes (3.11)
                processes = list(self.executor._processes.values())
                if not self._used:
                    for process in processes:
                        process.terminate()  # SIGTERM: the worker removes its folder, exits
                elif any(not future.done() for future in [*self._running, *self._given_ahead]):
                    for process in processes:
                        process.kill()
                self.executor.shutdown(cancel_futures=True)
            finally:
                shutil.rmtree(self.folder, ignore_errors=True)


class BoundPool:
    """A pool seen as the evaluator of one factory: its tasks run on that factory's workers.

    Closing it leaves the pool running: the pool's owner closes the pool.
    """

    def __init__(self, pool: SerialPool | ProcessPool, factory: WorkerFactory) -> None:
        self.pool = pool
        self.factory = factory
        self.workers = pool.workers
        self.ahead = pool.ahead

    def imap(self, tasks: Iterable[Any], in_flight: int | None = None) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) as :meth:`LocalPool.imap` does."""
        return self.pool.imap(tasks, self.factory, in_flight)

    def close(self) -> None:
        """Nothing to free: the pool belongs to its owner."""


def check_workers(workers: int | None) -> None:
    """A worker count must be a whole number >= 1 (None: all cores)."""
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ValueError(
            f"workers: expected a whole number >= 1 (or none for all cores), got {workers!r}"
        )


def make_pool(
    factory: WorkerFactory | None,
    workers: int | None,
    prepare: Callable[[], None] | None = None,
) -> SerialPool | ProcessPool:
    """Serial in this process for one worker, else a process pool started now (whose processes
    call ``prepare`` as they start)."""
    check_workers(workers)
    return SerialPool(factory) if workers == 1 else ProcessPool(factory, workers, prepare)


RunTask = tuple["Scenario", "TunedParameters | None"]  # a scenario and a set (None: its own)


def prepare_worker(modules: tuple[str, ...] = ()) -> None:
    """What a pool's process does as it starts, before its first task: import the co-simulation
    (numpy, fmpy), load the compiled master and import ``modules`` (those of its workers), while
    the parent prepares.

    A pool of campaign or diagnosis workers takes :func:`prepare_campaign_worker` or
    :func:`prepare_replay_worker`.
    """
    from twin_cosim.loops.ahead import ready_compiled_loops  # what this process is for

    ready_compiled_loops()
    for module in ("twin_cosim.cosim", *modules):
        importlib.import_module(module)


def prepare_campaign_worker() -> None:
    """:func:`prepare_worker` of a campaign's pool: the objective's modules too."""
    prepare_worker(("twin_cosim.optimize.objective",))


def prepare_replay_worker() -> None:
    """:func:`prepare_worker` of a diagnosis's pool: the replays (SciPy's optimizers are
    imported by the first fit: a worker that only replays never needs them)."""
    prepare_worker(("twin_cosim.gap.which.replay",))


@dataclass(frozen=True)
class PlantTasksSpec:
    """The recipe of a :class:`PlantTasks` worker: the FMU its plant loads, and what it answers
    for a task (a module-level function of the plant and the task, sent by reference)."""

    fmu: str
    answer: Callable[[Plant, Any], Any]

    def build(self) -> PlantTasks:
        """The worker, in the process that runs it."""
        return PlantTasks(self.fmu, self.answer)


class PlantTasks:
    """A worker answering tasks on one plant of its own."""

    def __init__(self, fmu: str, answer: Callable[[Plant, Any], Any]) -> None:
        from twin_cosim.plant import Plant  # the run's modules: in the workers only

        self.plant = Plant(fmu)
        self.answer = answer

    def __call__(self, task: Any) -> Any:
        """What the worker answers for ``task``."""
        return self.answer(self.plant, task)

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def scenario_record(plant: Plant, task: RunTask) -> RunRecord:
    """The record of a scenario run with a set (None: the scenario's own)
    (:func:`twin_cosim.cosim.run_scenario`)."""
    from twin_cosim.cosim import run_scenario  # in the workers only

    scenario, tuned = task
    return run_scenario(plant, scenario, tuned)


def autotune_proposal(plant: Plant, scenario: Scenario) -> dict[str, Any]:
    """The auto-tuner's proposal for a scenario from the twin's plant FRF measured on ``plant``
    (:func:`twin_cosim.frequency.autotune.propose`; ``twin autotune``'s layout)."""
    from twin_cosim.frequency.autotune import propose  # in the workers only

    proposal, _ = propose(plant, scenario)
    return proposal.summary()


def run_records(pool: SerialPool | ProcessPool, fmu: Path, tasks: list[RunTask]) -> list[RunRecord]:
    """The records of ``tasks`` run on ``fmu`` by the pool's workers, in task order."""
    found = dict(pool.imap(tasks, PlantTasksSpec(str(fmu), scenario_record)))
    return [found[i] for i in range(len(tasks))]


def autotune_summary(
    pool: SerialPool | ProcessPool, fmu: Path, scenario: Scenario
) -> dict[str, Any]:
    """The auto-tuner's proposal for ``scenario`` on ``fmu``, made by a worker of the pool."""
    [(_, summary)] = pool.imap([scenario], PlantTasksSpec(str(fmu), autotune_proposal))
    return summary
