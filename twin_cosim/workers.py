"""Worker pools for FMU work: each worker builds its own plant once and reuses it for every task.

A *factory* is a picklable object (plain values: paths, numbers, resolved scenarios) with a
``build()`` method returning the worker: a callable ``worker(task) -> result`` with a ``close()``
method. In a process pool every process calls ``build()`` once (spawned processes: an FMU is never
instantiated in a parent that then forks); tasks then run on that worker and results stream back
as they complete.

Nothing outlives a pool. Every pool has a private temp folder (``twin-pool-<parent pid>-*``) that
its workers extract FMUs into and that ``close()`` removes. A worker ignores Ctrl-C from the
moment it starts (it is spawned with SIGINT ignored, so a Ctrl-C while it still imports prints
no traceback; its parent handles Ctrl-C and shuts the pool down), frees its plant when it
exits, and dies with its parent: a watchdog thread polls the parent's pid, so after ``kill -9``
of the parent every worker removes the pool's folder and exits (the multiprocessing resource
tracker then ends too). A command of the ``twin`` CLI keeps all its temporary files in one such
folder (:func:`command_temp_folder`); one left by a process that could not clean up (``kill -9``
of a serial run) is removed by the next pool or command.
:func:`terminate_as_interrupt` makes SIGTERM end a process the way Ctrl-C does.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.util
import os
import re
import shutil
import signal
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Protocol

POOL_PREFIX = "twin-pool-"
PARENT_POLL_S = 0.2  # how often a worker checks that its parent is alive


class Worker(Protocol):
    """Does one task at a time on resources it holds (a plant)."""

    def __call__(self, task: Any) -> Any: ...

    def close(self) -> None: ...


class WorkerFactory(Protocol):
    """Picklable recipe of a worker."""

    def build(self) -> Worker: ...


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled like Ctrl-C, so that every ``finally`` runs."""


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated(f"signal {signum}")


def terminate_as_interrupt() -> None:
    """Make SIGTERM raise :class:`Terminated` (a KeyboardInterrupt) in the main thread."""
    signal.signal(signal.SIGTERM, _raise_terminated)


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


class SerialPool:
    """Runs the tasks one after the other in this process, on one worker."""

    def __init__(self, factory: WorkerFactory) -> None:
        self.folder = new_pool_folder()
        try:
            with _temp_root(self.folder):
                self.worker = factory.build()
        except BaseException:
            shutil.rmtree(self.folder, ignore_errors=True)
            raise
        self.workers = 1

    def imap(self, tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) for each task, in order."""
        for index, task in enumerate(tasks):
            yield index, self.worker(task)

    def close(self) -> None:
        """Free the worker's resources and remove its temp folder."""
        try:
            self.worker.close()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


_PROCESS_WORKER: Worker | None = None


def _close_process_worker(folder: str) -> None:
    if _PROCESS_WORKER is not None:
        _PROCESS_WORKER.close()
    shutil.rmtree(folder, ignore_errors=True)


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


def _build_in_process(factory: WorkerFactory, pool_folder: str, parent_pid: int) -> None:
    global _PROCESS_WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    folder = tempfile.mkdtemp(dir=pool_folder)
    tempfile.tempdir = folder
    _exit_on_sigterm(folder)
    threading.Thread(target=_watch_parent, args=(parent_pid, pool_folder), daemon=True).start()
    multiprocessing.util.Finalize(None, _close_process_worker, args=(folder,), exitpriority=10)
    _PROCESS_WORKER = factory.build()


@contextmanager
def _children_ignore_interrupts() -> Iterator[None]:
    """Start processes in this block with SIGINT ignored; this process keeps its Ctrl-C.

    SIGINT is blocked, then ignored: a spawned interpreter inherits the ignored disposition
    (and then installs no Ctrl-C handler of its own), while a Ctrl-C that arrives here meanwhile
    stays pending (a blocked signal is never discarded as ignored) and reaches the restored
    handler when the block ends. Outside the main thread (where handlers cannot change) nothing
    changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, held)


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
        Number of processes (>= 1); all cores when None.
    """

    def __init__(self, factory: WorkerFactory, workers: int | None = None) -> None:
        check_workers(workers)
        self.workers = workers or os.cpu_count() or 1
        self.folder = new_pool_folder()
        self.executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_build_in_process,
            initargs=(factory, self.folder, os.getpid()),
        )

    def imap(self, tasks: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """Yield (task index, result) in order of completion."""
        with _children_ignore_interrupts():  # a submit may spawn the pool's processes
            futures = {
                self.executor.submit(_run_in_process, task): i for i, task in enumerate(tasks)
            }
        for future in as_completed(futures):
            yield futures[future], future.result()

    def close(self) -> None:
        """Shut the pool down (workers free their plants) and remove its temp folder."""
        try:
            self.executor.shutdown(cancel_futures=True)
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


def check_workers(workers: int | None) -> None:
    """A worker count must be a whole number >= 1 (None: all cores)."""
    if workers is not None and (
        isinstance(workers, bool) or not isinstance(workers, int) or workers < 1
    ):
        raise ValueError(
            f"workers: expected a whole number >= 1 (or none for all cores), got {workers!r}"
        )


def make_pool(factory: WorkerFactory, workers: int | None):
    """Serial in this process for one worker, else a process pool."""
    check_workers(workers)
    return SerialPool(factory) if workers == 1 else ProcessPool(factory, workers)
