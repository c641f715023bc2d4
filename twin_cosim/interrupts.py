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
"""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

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
