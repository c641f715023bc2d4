"""What every evaluator of candidates offers, and what it may raise.

An evaluator (serial, a local process pool of :mod:`twin_cosim.workers`, or Dask in
:mod:`twin_cosim.optimize.dask_evaluator`) scores tasks on its workers and streams back
``(row index, result)`` pairs as they complete; a result is the dict an
:class:`~twin_cosim.optimize.objective.Objective` returns.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any, Protocol

Result = dict[str, Any]


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
