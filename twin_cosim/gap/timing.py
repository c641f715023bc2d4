"""Where a diagnosis spends its time: wall seconds, pool tasks and replays per phase."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field


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
    """

    wall_s: float = 0.0
    tasks: int = 0
    replays: int = 0


@dataclass
class PhaseTimes:
    """Totals per phase, in the order the phases first ran."""

    phases: dict[str, Phase] = field(default_factory=dict)

    @contextmanager
    def timed(self, phase: str, tasks: int) -> Iterator[Phase]:
        """Time a batch of ``tasks`` pool tasks of ``phase``; the caller adds the replays."""
        entry = self.phases.setdefault(phase, Phase())
        start = time.perf_counter()
        try:
            yield entry
        finally:
            entry.wall_s += time.perf_counter() - start
            entry.tasks += tasks

    def as_dict(self) -> dict[str, dict[str, float]]:
        """JSON-ready totals, with the total wall time of the phases."""
        table = {
            name: {"wall_s": p.wall_s, "tasks": p.tasks, "replays": p.replays}
            for name, p in self.phases.items()
        }
        table["total"] = {
            "wall_s": sum(p.wall_s for p in self.phases.values()),
            "tasks": sum(p.tasks for p in self.phases.values()),
            "replays": sum(p.replays for p in self.phases.values()),
        }
        return table
