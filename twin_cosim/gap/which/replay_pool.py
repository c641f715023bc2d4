"""The replay workers as the selection uses them, and where the time goes.

:class:`ReplayPool` runs tasks (:mod:`twin_cosim.gap.which.replay`) on the pool in task order,
each batch timed under a phase of the selection; keeps the calibration directions around every
parameter set it was asked for (the joint refits and the backward pass ask for the same sets
again); fits the calibration correction of a model, replayed and re-linearised where the
linear correction leaves a gap; and replays a model with its best calibration correction.

Where the time goes: wall seconds, pool tasks, replays and CPU per phase. Wall time on shared
cores says as much about the other load as about the diagnosis, so each pool task also reports
the CPU time it took (:class:`~twin_cosim.gap.which.replay.Timed`), and each batch of tasks the
wall time it would take on otherwise idle workers (:func:`makespan`): a figure that does not
depend on the machine's load.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.floors.evidence import CalibrationBasis, CalibrationFloor, floor_of
from twin_cosim.gap.which.acceptance import Judging
from twin_cosim.gap.which.replay import FitResult, Replays, SimulateTask, Uncertainty

if TYPE_CHECKING:
    from twin_cosim.workers import BoundPool

Progress = Callable[[int], None]

REFINEMENTS = 2  # re-linearisations of a calibration correction, at most
REFINEMENT_GAIN = 0.05  # the least relative cut of what is left that earns a further one


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


def _replays_of(result: FitResult | Replays | Uncertainty) -> int:
    """Replays a task ran: a fit's (or an uncertainty's) count, or one per judging scenario."""
    return len(result.judging) if isinstance(result, Replays) else result.replays


@dataclass
class ReplayPool:
    """Replays and fits of the selection on a pool of replay workers.

    Parameters
    ----------
    pool : BoundPool
        Pool of :class:`~twin_cosim.gap.which.replay.Replayer` workers.
    nominal : dict
        Nominal FMU parameters of the twin (noise model included).
    calibrated : list of str
        The calibrated parameters (the model card's, those the FMU has).
    judging : Judging
        The held-out runs.
    tolerance : float
        Relative uncertainty of the calibrated parameters.
    progress : callable or None
        Called with the number of tasks done.
    times : PhaseTimes
        Where the time went, per phase.
    bases : dict
        The calibration directions of each parameter set asked for.
    """

    pool: BoundPool
    nominal: dict[str, float]
    calibrated: list[str]
    judging: Judging
    tolerance: float
    progress: Progress | None = None
    times: PhaseTimes = field(default_factory=PhaseTimes)
    bases: dict[tuple, CalibrationBasis] = field(default_factory=dict, repr=False)

    def tasks(self, phase: str, tasks: list) -> list:
        """Results of tasks on the pool, in task order, reporting each completion; the time
        they took and the replays they ran go to ``phase``."""
        results: list = [None] * len(tasks)
        cpu = [0.0] * len(tasks)
        with self.times.timed(phase, len(tasks)) as totals:
            for i, timed in self.pool.imap(tasks):
                results[i], cpu[i] = timed.result, timed.cpu_s
                totals.replays += _replays_of(timed.result)
                if self.progress:
                    self.progress(1)
            totals.cpu_s += sum(cpu)
            totals.idle_wall_s += makespan(cpu, self.pool.workers)
        return results

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        """Calibration directions around the parameter set ``nominal + base`` (each set's
        replayed once)."""
        key = tuple(sorted(base.items()))
        if key not in self.bases:
            self.bases[key] = self._new_basis(base)
        return self.bases[key]

    def _new_basis(self, base: dict[str, float]) -> CalibrationBasis:
        current = {**self.nominal, **base}
        moves = [
            {**base, name: current[name] * (1.0 + sign * self.tolerance)}
            for name in self.calibrated
            for sign in (1.0, -1.0)
        ]
        replays = self.tasks("calibration_directions", [SimulateTask(m) for m in moves])
        columns = []
        for i in range(0, len(moves), 2):
            up = self.judging.vector(self.judging.residuals(replays[i]))
            down = self.judging.vector(self.judging.residuals(replays[i + 1]))
            columns.append(0.5 * (down - up))  # residual = measured - simulated
        directions = np.column_stack(columns) if columns else np.zeros((0, 0))
        return CalibrationBasis(self.calibrated, directions)

    def left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        """The normalised held-out residual the best calibration correction leaves of the
        replays of the parameter set ``nominal + overrides``."""
        vector = self.judging.vector(self.judging.residuals(replays))
        return self.basis(overrides).correction(vector)[1]

    def calibration(
        self, base: dict[str, float], replays: Replays, threshold: float
    ) -> tuple[CalibrationFloor, Replays]:
        """The calibration floor of the held-out residual of ``replays`` (the parameter set
        ``nominal + base``) and the replays with its correction applied.

        The correction is first the linear one of the calibration directions around ``base``
        (:func:`~twin_cosim.gap.floors.evidence.floor_of`). The directions are centred
        differences, one parameter at a time: a combined change of several calibrated
        parameters is not the sum of their effects, and the linear correction can leave a gap
        that calibration error explains. Where what it leaves is at or above ``threshold``
        (normalised RMS: a gap), the correction is re-linearised around the corrected
        parameters and replayed (Gauss-Newton steps within the tolerance, at most
        :data:`REFINEMENTS`, a further one only after a step that cut what is left by
        :data:`REFINEMENT_GAIN`). The floor keeps the replayed correction when its replay
        leaves less than the linear correction is predicted to leave: calibration error gets
        every benefit of the doubt.

        Parameters
        ----------
        base : dict
            FMU parameters of the model on top of the nominal twin.
        replays : Replays
            Its replays.
        threshold : float
            Normalised RMS at which what is left is a gap.
        """
        vector = self.judging.vector(self.judging.residuals(replays))
        floor = floor_of(self.basis(base), vector)
        calibrated = self.calibrated_replay(base, floor)
        if floor.left < threshold or not self.calibrated:
            return floor, calibrated
        step = np.array([floor.coefficients[n] for n in self.calibrated])
        step_left = float(np.linalg.norm(self.judging.vector(self.judging.residuals(calibrated))))
        best, best_replays = floor, calibrated
        for _ in range(REFINEMENTS):
            scale = 1.0 + step * self.tolerance
            corrected = self._corrected(base, dict(zip(self.calibrated, step, strict=True)))
            delta, _ = self.basis(corrected).correction(
                self.judging.vector(self.judging.residuals(calibrated)),
                bounds=(
                    ((1.0 - self.tolerance) / scale - 1.0) / self.tolerance,
                    ((1.0 + self.tolerance) / scale - 1.0) / self.tolerance,
                ),
            )
            step = (scale * (1.0 + delta * self.tolerance) - 1.0) / self.tolerance
            trial = CalibrationFloor(
                floor.before, 0.0, 0.0, dict(zip(self.calibrated, step.tolist(), strict=True))
            )
            calibrated = self.calibrated_replay(base, trial)
            left = float(np.linalg.norm(self.judging.vector(self.judging.residuals(calibrated))))
            if left < best.left:
                explained = math.sqrt(max(floor.before**2 - left**2, 0.0))
                best = CalibrationFloor(floor.before, left, explained, trial.coefficients)
                best_replays = calibrated
            if left >= threshold and left <= step_left * (1.0 - REFINEMENT_GAIN):
                step_left = left
                continue
            break
        return best, best_replays

    def _corrected(
        self, base: dict[str, float], coefficients: dict[str, float]
    ) -> dict[str, float]:
        """``base`` with the calibration correction ``coefficients`` (tolerances) applied."""
        current = {**self.nominal, **base}
        return {
            **base,
            **{n: current[n] * (1.0 + a * self.tolerance) for n, a in coefficients.items()},
        }

    def calibrated_replay(self, base: dict[str, float], floor: CalibrationFloor) -> Replays:
        """Replays with the best calibration correction applied to the calibrated parameters."""
        corrected = self._corrected(base, floor.coefficients)
        return self.tasks("calibrated_replays", [SimulateTask(corrected)])[0]
