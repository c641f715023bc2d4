"""Where a diagnosis spends its time: wall seconds, pool tasks, replays and CPU per phase.

Wall time on shared cores says as much about the other load as about the diagnosis, so each
pool task also reports the CPU time it took (:class:`Timed`), and each batch of tasks the wall
time it would take on otherwise idle workers (:func:`makespan`): a figure that does not depend
on the machine's load.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Timed:
    """A pool task's result and the CPU time (s) the worker spent on it."""

    result: Any
    cpu_s: float


def makespan(durations: list[float], workers: int) -> float:
    """Wall time (s) of tasks of these durations (s) handed, in order, to the first free of
    ``workers`` workers (as a process pool does)."""
    free = [0.0] * max(workers, 1)
    for duration in durations:
        free[free.index(min(free))] += duration
    return max(free)


@dataclass
class Phase:
    """One phase's totals.

    Attributes
    ----------
    wall_s : float
        Wall time spent waiting for the phase's tasks, s.
    tasks : int
        Pool tasks (a fit, a replay of the judging runs, a joint refit).
    replays : int
        Replays the tasks ran (a fit's training replays, one per replayed scenario).
    cpu_s : float
        CPU time of the tasks in the workers, s.
    idle_wall_s : float
        Wall time the phase's batches would take on otherwise idle workers, s.
    """

    wall_s: float = 0.0
    tasks: int = 0
    replays: int = 0
    cpu_s: float = 0.0
    idle_wall_s: float = 0.0


@dataclass
class PhaseTimes:
    """Totals per phase, in the order the phases first ran."""

    phases: dict[str, Phase] = field(default_factory=dict)

    @contextmanager
    def timed(self, phase: str, tasks: int) -> Iterator[Phase]:
        """Time a batch of ``tasks`` pool tasks of ``phase``; the caller adds the replays and
        the CPU figures."""
        entry = self.phases.setdefault(phase, Phase())
        start = time.perf_counter()
        try:
            yield entry
        finally:
            entry.wall_s += time.perf_counter() - start
            entry.tasks += tasks

    def as_dict(self) -> dict[str, dict[str, float]]:
        """JSON-ready totals per phase and over all phases (``total``)."""
        table = {name: dict(vars(p)) for name, p in self.phases.items()}
        table["total"] = {
            key: sum(getattr(p, key) for p in self.phases.values()) for key in vars(Phase())
        }
        return table
