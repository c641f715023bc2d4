"""A forked process that imports matplotlib while its command computes, then draws its figures.

matplotlib's import (about a third of a second) and the drawing are most of what a user waits
for when a quick command ends with a figure. A command forks the painter at its start, before it
loads a plant or numpy (nothing to inherit but the interpreter), goes on with its work, writes
its results, then hands the painter the drawing function and its arguments and waits for the
figure (a drawing function may draw several side by side: :func:`draw_side_by_side`). A
command that knows part of its figure's data early (e.g. the run of a campaign's own set) hands
the painter that computation first (:meth:`Painter.prepare`): the painter does it while the
command works, and its drawing function receives the value. The painter ends without drawing
when its command ends without handing it a figure (an error, an interrupt, ``kill -9``: the pipe
closes). Where ``os.fork`` does not exist the figure is drawn in the command's own process.
"""

from __future__ import annotations

import importlib
import os
import pickle
import signal
import sys
from collections.abc import Callable
from typing import Any, BinaryIO

# Called by the painter while it waits: imports matplotlib, its PNG backend and fonts
WARM_UP = "twin_cosim.plots:warm_up"

# The messages a command hands its painter: (kind, "module:function", arguments), pickled
_PREPARE = "prepare"
_DRAW = "draw"


class Painter:
    """One figure drawn by a forked process (or here, without ``os.fork``).

    Use :meth:`start` at the command's start, :meth:`prepare` (optional) once the figure's
    early data is known, :meth:`draw` once its results are written. A message is small (the
    painter computes what it needs from it): a command never waits for a busy painter to read.
    """

    def __init__(self, pid: int | None, pipe: BinaryIO | None) -> None:
        self.pid = pid
        self.pipe = pipe
        self._preparation: tuple[str, tuple[Any, ...]] | None = None  # without os.fork

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
        return cls(pid, os.fdopen(write_end, "wb"))

    def prepare(self, function: str, *arguments: Any) -> None:
        """Have the painter compute ``function(*arguments)`` now, while this process goes on;
        the drawing function of :meth:`draw` receives its value as its first argument.

        ``function`` is named ``"module:function"``, like the drawing function.
        """
        if self.pid is None:
            self._preparation = (function, arguments)
            return
        self._send(_PREPARE, function, arguments)

    def draw(self, function: str, *arguments: Any) -> bool:
        """Draw ``function(*arguments)`` (after :meth:`prepare`: ``function(prepared,
        *arguments)``) and wait for it; True when the figure was drawn (the painter says why on
        stderr otherwise).

        ``function`` is named ``"module:function"``, so that this process never imports what
        draws (matplotlib).
        """
        if self.pid is None:
            if self._preparation is not None:
                prepare, given = self._preparation
                arguments = (_resolve(prepare)(*given), *arguments)
            _resolve(function)(*arguments)
            return True
        self._send(_DRAW, function, arguments)
        self._close_pipe()
        return self._wait() == 0

    def close(self) -> None:
        """End the painter without a figure (its command ends without one)."""
        self._close_pipe()
        if self.pid is not None:
            self._wait()

    def _send(self, kind: str, function: str, arguments: tuple[Any, ...]) -> None:
        """Hand the painter one message (a painter that died said why; :meth:`draw` reports
        its status)."""
        try:
            pickle.dump((kind, function, arguments), self.pipe, pickle.HIGHEST_PROTOCOL)
            self.pipe.flush()
        except BrokenPipeError:
            pass

    def _close_pipe(self) -> None:
        """Close this end of the pipe: the painter reads the end of its messages."""
        if self.pipe is None:
            return
        try:
            self.pipe.close()
        except BrokenPipeError:  # what was left to flush had no reader
            pass
        self.pipe = None

    def _wait(self) -> int:
        """The painter's exit status (0: drawn), once it has ended."""
        _, status = os.waitpid(self.pid, 0)
        self.pid = None
        return os.waitstatus_to_exitcode(status)


def _paint(read_end: int) -> int:  # pragma: no cover - runs in the forked child
    """The painter's life: import, then the command's messages: compute what is to prepare,
    draw the figure (no figure: end); the exit code."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends it with its command
        _resolve(WARM_UP)()
        prepared: tuple[Any, ...] = ()
        with os.fdopen(read_end, "rb") as pipe:
            while True:
                try:
                    kind, function, arguments = pickle.load(pipe)
                except EOFError:  # the command ended without a figure
                    return 0
                if kind == _PREPARE:
                    prepared = (_resolve(function)(*arguments),)
                    continue
                _resolve(function)(*prepared, *arguments)
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
