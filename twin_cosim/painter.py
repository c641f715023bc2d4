"""A forked process that imports matplotlib while its command computes, then draws its figures.

matplotlib's import (about a third of a second) and the drawing are most of what a user waits
for when a quick command ends with a figure. A command forks the painter at its start, before it
loads a plant or numpy (nothing to inherit but the interpreter), goes on with its work, writes
its results, then hands the painter the drawing function and its arguments and waits for the
figure (a drawing function may draw several side by side: :func:`draw_side_by_side`). The
painter ends without drawing when its command ends without handing it anything (an
error, an interrupt, ``kill -9``: the pipe closes). Where ``os.fork`` does not exist the figure
is drawn in the command's own process.
"""

from __future__ import annotations

import importlib
import os
import pickle
import signal
import sys
from collections.abc import Callable
from typing import Any

# Called by the painter while it waits: imports matplotlib, its PNG backend and fonts
WARM_UP = "twin_cosim.plots:warm_up"


class Painter:
    """One figure drawn by a forked process (or here, without ``os.fork``).

    Use :meth:`start` at the command's start, :meth:`draw` once its results are written.
    """

    def __init__(self, pid: int | None, write_end: int | None) -> None:
        self.pid = pid
        self.write_end = write_end

    @classmethod
    def start(cls) -> Painter:
        """Fork the painter (it runs :data:`WARM_UP`, then waits for its figure)."""
        if not hasattr(os, "fork"):
            return cls(None, None)
        read_end, write_end = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - runs in the child; its exit code is what is tested
            os.close(write_end)
            os._exit(_paint(read_end))
        os.close(read_end)
        return cls(pid, write_end)

    def draw(self, function: str, *arguments: Any) -> bool:
        """Draw ``function(*arguments)`` and wait for it; True when the figure was drawn (the
        painter says why on stderr otherwise).

        ``function`` is named ``"module:function"``, so that this process never imports what
        draws (matplotlib).
        """
        if self.pid is None:
            _resolve(function)(*arguments)
            return True
        payload = pickle.dumps((function, arguments), protocol=pickle.HIGHEST_PROTOCOL)
        try:
            with os.fdopen(self.write_end, "wb") as pipe:
                self.write_end = None
                pipe.write(payload)
        except BrokenPipeError:  # the painter died (it said why)
            pass
        return self._wait() == 0

    def close(self) -> None:
        """End the painter without a figure (its command ends without one)."""
        if self.write_end is not None:
            os.close(self.write_end)
            self.write_end = None
        if self.pid is not None:
            self._wait()

    def _wait(self) -> int:
        """The painter's exit status (0: drawn), once it has ended."""
        _, status = os.waitpid(self.pid, 0)
        self.pid = None
        return os.waitstatus_to_exitcode(status)


def _paint(read_end: int) -> int:  # pragma: no cover - runs in the forked child
    """The painter's life: import, read its figure (none: end), draw; the exit code."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends it with its command
        _resolve(WARM_UP)()
        with os.fdopen(read_end, "rb") as pipe:
            payload = pipe.read()
        if not payload:
            return 0
        function, arguments = pickle.loads(payload)
        _resolve(function)(*arguments)
        return 0
    except Exception as error:  # any failure of the drawing: said, and the figure is missing
        print(f"twin: error: the figure was not drawn: {error}", file=sys.stderr, flush=True)
        return 1


def draw_side_by_side(*figures: Callable[[], object]) -> None:
    """Draw several figures at once: each but the last in a process forked from this one (which
    shares what this one has loaded, e.g. a warm matplotlib), the last here; sequentially where
    ``os.fork`` does not exist.

    Raises
    ------
    RuntimeError
        When a forked drawing failed (it said why on stderr).
    """
    if not hasattr(os, "fork"):
        for figure in figures:
            figure()
        return
    children = []
    sys.stdout.flush()
    sys.stderr.flush()
    for figure in figures[:-1]:
        pid = os.fork()
        if pid == 0:  # pragma: no cover - runs in the child; its exit code is what is tested
            os._exit(_draw_here(figure))
        children.append(pid)
    try:
        figures[-1]()
    finally:
        failed = sum(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) != 0 for pid in children)
    if failed:
        raise RuntimeError(f"{failed} of {len(figures)} figures drawn side by side failed")


def _draw_here(figure: Callable[[], object]) -> int:  # pragma: no cover - in a forked child
    """Draw ``figure`` in this (forked) process; the exit code (1: failed, said on stderr)."""
    try:
        figure()
        return 0
    except Exception as error:
        print(f"twin: error: the figure was not drawn: {error}", file=sys.stderr, flush=True)
        return 1
    finally:
        sys.stdout.flush()
        sys.stderr.flush()


def _resolve(function: str) -> Any:
    """The function named ``"module:function"``."""
    module, name = function.split(":")
    return getattr(importlib.import_module(module), name)
