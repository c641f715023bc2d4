"""The replay workers as the selection uses them, and where the time goes.

:class:`ReplayPool` runs tasks (:mod:`twin_cosim.gap.which.replay`) on the pool in task order,
each batch timed under a phase of the selection; keeps the calibration directions around every
parameter set it was asked for (the joint refits and the backward pass ask for the same sets
again); fits the calibration correction of a model, replayed and re-linearised where the
linear correction leaves a gap; and replays a model with its best calibration correction.

Replays of the judging runs by parameter set (:class:`JudgingCache`): a replay is deterministic,
so a parameter set asked for again (the sequential model a joint refit is judged against, the
candidate replay of the accepted effect, a calibration direction of a model seen before) is
answered with the records of its first replay instead of a pool task; so is the training
residual of a parameter set whose training replays it keeps (a time split's judging replays hold
them: the uncertainty's calibrated columns are the calibration directions' sets).

Where the time goes: wall seconds, pool tasks, replays and CPU per phase. Wall time on shared
cores says as much about the other load as about the diagnosis, so each pool task also reports
the CPU time it took (:class:`~twin_cosim.gap.which.replay.Timed`), and each batch of tasks the
wall time it would take on otherwise idle workers (:func:`makespan`): a figure that does not
depend on the machine's load. Per fit (a hypothesis' fit, a joint refit): its replays, the
iterations of its local fit, the replays of its start's search, its CPU and wall time.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from threadpoolctl import threadpool_limits

from twin_cosim.gap.floors.evidence import CalibrationBasis, CalibrationFloor, floor_of
from twin_cosim.gap.which.acceptance import Judging
from twin_cosim.gap.which.replay import (
    FitResult,
    JointFitTask,
    JointProblem,
    ParameterKey,
    Replays,
    ReplaySpec,
    ResidualTask,
    SimulateTask,
    Timed,
    Uncertainty,
    UncertaintyTask,
    failure_residual,
    linearised_uncertainty,
    normalised_residual,
)

if TYPE_CHECKING:
    from twin_cosim.plant_model import Hypothesis
    from twin_cosim.run_record import RunRecord
    from twin_cosim.workers import BoundPool, Started

Progress = Callable[[int], None]
# Bytes of judging replays the parent keeps (16 of the 12.4 s of scenarios/diagnosis.yaml, 3.6
# MB each): the repeats of a diagnosis come within a few batches.
JUDGING_CACHE_BYTES = 64 * 2**20
# Bytes of training residuals the parent keeps (0.4 MB each on scenarios/diagnosis.yaml): a
# model's calibration directions (its uncertainty's columns) outlive the records of later models.
RESIDUAL_CACHE_BYTES = 64 * 2**20

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
        Replays the tasks asked for (a fit's training replays, one per judging scenario of a
        replay task), whether run or answered by a cache.
    cpu_s : float
        CPU time of the tasks in the workers, s.
    idle_wall_s : float
        Wall time the phase's batches would take on otherwise idle workers, s.
    replays_run : int
        Replays the workers ran (a fit's replay of its base model included).
    cache_hits : int
        Replays answered by a cache (the workers' training residuals, the judging replays and
        the training residuals the parent keeps of them).
    fits : list of dict
        Per fit task, in the order they were handed out: ``fit`` (the hypothesis, or the
        joint refit's ``a+b``), ``replays``, ``replays_run``, ``cache_hits``, ``iterations``
        (of its local least-squares fit), ``search_replays`` (of its start's search or scan),
        ``cpu_s`` and ``wall_s`` in the worker.
    """

    wall_s: float = 0.0
    tasks: int = 0
    replays: int = 0
    cpu_s: float = 0.0
    idle_wall_s: float = 0.0
    replays_run: int = 0
    cache_hits: int = 0
    fits: list[dict[str, Any]] = field(default_factory=list)


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

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """JSON-ready totals per phase (with its fits) and over all phases (``total``)."""
        table: dict[str, dict[str, Any]] = {
            name: {**vars(p), "fits": list(p.fits)} for name, p in self.phases.items()
        }
        counted = [key for key in vars(Phase()) if key != "fits"]
        table["total"] = {
            key: sum(getattr(p, key) for p in self.phases.values()) for key in counted
        }
        return table


def fit_record(timed: Timed) -> dict[str, Any] | None:
    """What a fit task cost (:attr:`Phase.fits`), or None for another task."""
    fit = timed.result
    if not isinstance(fit, FitResult):
        return None
    return {
        "fit": fit.hypothesis,
        "replays": fit.replays,
        "replays_run": timed.replays_run,
        "cache_hits": timed.cache_hits,
        "iterations": fit.iterations,
        "search_replays": fit.search_replays,
        "cpu_s": timed.cpu_s,
        "wall_s": timed.wall_s,
    }


def _record_bytes(replays: Replays) -> int:
    """Bytes of the distinct records of a task's replays."""
    records = {id(r): r for r in [*(replays.training or []), *replays.judging]}
    return sum(r.to_numpy().nbytes for r in records.values())


@dataclass
class JudgingCache:
    """Replays of :class:`~twin_cosim.gap.which.replay.SimulateTask` by the parameter set they
    ran with, the latest kept up to :data:`JUDGING_CACHE_BYTES`; and the training residuals of
    those that hold the training replays, the latest kept up to :data:`RESIDUAL_CACHE_BYTES`.

    Parameters
    ----------
    key : callable
        The parameter set of a task's overrides
        (:meth:`~twin_cosim.gap.which.replay.ReplaySpec.key`).
    training_in_judging : list of int or None
        Per training scenario the index of the same judging scenario (a time split: the
        training replays are judging replays), or None.
    training_residual : callable or None
        The normalised training residual of the training replays (None: none kept).
    size_bytes : int
        Bytes of records kept.
    residual_bytes : int
        Bytes of training residuals kept.
    entries : OrderedDict
        The replays by (parameter set, with training replays), the latest last.
    residuals : OrderedDict
        The normalised training residuals by parameter set, the latest last.
    entry_bytes : dict
        Bytes of the records of each entry.
    kept_bytes, kept_residual_bytes : int
        Bytes of the records and of the training residuals kept (running sums: a put costs
        the bytes of its own replays, not of all kept).
    """

    key: Callable[[dict[str, float]], ParameterKey]
    training_in_judging: list[int] | None
    training_residual: Callable[[list[RunRecord]], np.ndarray] | None = None
    size_bytes: int = JUDGING_CACHE_BYTES
    residual_bytes: int = RESIDUAL_CACHE_BYTES
    entries: OrderedDict[tuple[ParameterKey, bool], Replays] = field(
        default_factory=OrderedDict, repr=False
    )
    residuals: OrderedDict[ParameterKey, np.ndarray] = field(
        default_factory=OrderedDict, repr=False
    )
    entry_bytes: dict[tuple[ParameterKey, bool], int] = field(default_factory=dict, repr=False)
    kept_bytes: int = 0
    kept_residual_bytes: int = 0

    @classmethod
    def of(cls, spec: ReplaySpec) -> JudgingCache:
        """The cache of the replays of ``spec``'s workers, with their training residuals (of
        the training replays cut where a worker's end: the same numbers)."""
        return cls(
            spec.key,
            spec.training_in_judging(),
            lambda records: normalised_residual(spec.training_records(records), spec.training),
        )

    def get(self, task: SimulateTask) -> Replays | None:
        """The replays of the task's parameter set when kept (with the training replays when
        asked and known), else None."""
        key = self.key(task.overrides)
        for with_training in (task.with_training, not task.with_training):
            found = self.entries.get((key, with_training))
            if found is None:
                continue
            self.entries.move_to_end((key, with_training))
            if not task.with_training:
                return Replays(None, found.judging)
            training = self._training(found)
            if training is not None:
                return Replays(training, found.judging)
        return None

    def residual(self, overrides: dict[str, float]) -> np.ndarray | None:
        """The normalised training residual of the parameter set ``nominal + overrides`` when
        kept, else None."""
        key = self.key(overrides)
        found = self.residuals.get(key)
        if found is None:
            return None
        self.residuals.move_to_end(key)
        return found.copy()

    def put(self, task: SimulateTask, replays: Replays) -> None:
        """Keep the replays of the task's parameter set, and their training residual when they
        hold the training replays."""
        key = self.key(task.overrides)
        entry = (key, task.with_training)
        size = _record_bytes(replays)
        self.kept_bytes += size - self.entry_bytes.get(entry, 0)
        self.entries[entry] = replays
        self.entry_bytes[entry] = size
        while self.kept_bytes > self.size_bytes:
            oldest, _ = self.entries.popitem(last=False)
            self.kept_bytes -= self.entry_bytes.pop(oldest)
        training = self._training(replays)
        if self.training_residual is None or training is None or key in self.residuals:
            return
        self.residuals[key] = self.training_residual(training)
        self.kept_residual_bytes += self.residuals[key].nbytes
        while self.kept_residual_bytes > self.residual_bytes:
            _, dropped = self.residuals.popitem(last=False)
            self.kept_residual_bytes -= dropped.nbytes

    def _training(self, replays: Replays) -> list[RunRecord] | None:
        """The training replays among ``replays`` (a time split's are judging replays), or
        None."""
        if replays.training is not None:
            return replays.training
        if self.training_in_judging is not None:
            return [replays.judging[i] for i in self.training_in_judging]
        return None


def calibration_moves(
    nominal: dict[str, float], base: dict[str, float], calibrated: list[str], tolerance: float
) -> list[SimulateTask]:
    """The replays of the calibration directions around the parameter set ``nominal + base``:
    each calibrated parameter moved by one relative ``tolerance`` up, then down."""
    current = {**nominal, **base}
    return [
        SimulateTask({**base, name: current[name] * (1.0 + sign * tolerance)})
        for name in calibrated
        for sign in (1.0, -1.0)
    ]


def _replays_of(result: FitResult | Replays | np.ndarray) -> int:
    """Replays a task ran: a fit's count, one per judging scenario, or one training residual's
    parameter set."""
    if isinstance(result, np.ndarray):
        return 1
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
    cache : JudgingCache or None
        The judging replays and training residuals kept by parameter set (None: every replay
        and residual task runs).
    nominal_directions : Started or None
        The calibration directions around the nominal twin (:func:`calibration_moves` with
        nothing on top), started on the pool before it was made (None: none were); taken by
        the first basis of the nominal twin when they are its tasks, else cancelled.
    """

    pool: BoundPool
    nominal: dict[str, float]
    calibrated: list[str]
    judging: Judging
    tolerance: float
    progress: Progress | None = None
    times: PhaseTimes = field(default_factory=PhaseTimes)
    bases: dict[tuple, CalibrationBasis] = field(default_factory=dict, repr=False)
    cache: JudgingCache | None = None
    nominal_directions: Started | None = None

    def tasks(self, phase: str, tasks: list, started: Started | None = None) -> list:
        """Results of tasks on the pool, in task order, reporting each completion; the time
        they took and the replays they asked for go to ``phase``. A replay task whose
        parameter set was replayed before (or earlier in the batch) is answered from the
        cache, and so is a residual task whose training replays it keeps. ``started``: the
        tasks were all given out already (:meth:`~twin_cosim.workers.LocalPool.start`)."""
        results: list = [None] * len(tasks)
        cpu = [0.0] * len(tasks)
        sent, repeats = (list(range(len(tasks))), []) if started else self._to_run(tasks, results)
        stream = started.results() if started else self.pool.imap([tasks[i] for i in sent])
        fits: dict[int, dict[str, Any]] = {}
        with self.times.timed(phase, len(tasks)) as totals:
            for j, timed in stream:
                i = sent[j]
                results[i], cpu[i] = timed.result, timed.cpu_s
                totals.replays_run += timed.replays_run
                totals.cache_hits += timed.cache_hits
                if (record := fit_record(timed)) is not None:
                    fits[i] = record
                if self.cache is not None and isinstance(tasks[i], SimulateTask):
                    self.cache.put(tasks[i], timed.result)
                if self.progress:
                    self.progress(1)
            for i, first in repeats:
                results[i] = results[first]
            answered = set(range(len(tasks))) - set(sent)
            for i, result in enumerate(results):
                totals.replays += _replays_of(result)
                if i in answered:
                    totals.cache_hits += _replays_of(result)
                    if self.progress:
                        self.progress(1)
            totals.fits.extend(fits[i] for i in sorted(fits))
            totals.cpu_s += sum(cpu)
            totals.idle_wall_s += makespan(cpu, self.pool.workers)
        return results

    def _to_run(self, tasks: list, results: list) -> tuple[list[int], list[tuple[int, int]]]:
        """The indices of the tasks to send to the pool, and (index, index of the same task
        sent) of replay tasks repeated within the batch; the replay and residual tasks the cache
        answers get their results in ``results`` now."""
        sent: list[int] = []
        repeats: list[tuple[int, int]] = []
        first: dict[tuple[ParameterKey, bool], int] = {}
        for i, task in enumerate(tasks):
            if isinstance(task, ResidualTask) and self.cache is not None:
                # the residual a worker would compute, number for number, from a replay kept here
                if (residual := self.cache.residual(task.overrides)) is not None:
                    results[i] = residual
                    continue
            if self.cache is None or not isinstance(task, SimulateTask):
                sent.append(i)
                continue
            key = (self.cache.key(task.overrides), task.with_training)
            if key in first:
                repeats.append((i, first[key]))
            elif (kept := self.cache.get(task)) is not None:
                results[i] = kept
            else:
                first[key] = i
                sent.append(i)
        return sent, repeats

    def keep(self, overrides: dict[str, float], replays: Replays) -> None:
        """Keep ``replays``, made elsewhere, as those of the parameter set ``nominal +
        overrides`` (the nominal twin's, replayed before the pool's work): asked for again,
        they answer as the pool's own would. Kept only when that set lies within the FMU's
        ranges, as the workers' sets are clipped."""
        parameters = tuple(sorted({**self.nominal, **overrides}.items()))
        if self.cache is not None and self.cache.key(overrides) == parameters:  # none clipped
            self.cache.put(
                SimulateTask(overrides, with_training=replays.training is not None), replays
            )

    def uncertainty(self, task: UncertaintyTask, hypotheses: dict[str, Hypothesis]) -> Uncertainty:
        """What the training data leave uncertain in a model
        (:func:`~twin_cosim.gap.which.replay.linearised_uncertainty`): the residuals of its
        Jacobian's columns run as one batch of pool tasks, side by side on the workers."""
        spec = self.pool.factory  # the workers' recipe: nominal plant, ranges, training data
        assert isinstance(spec, ReplaySpec)
        return linearised_uncertainty(
            task,
            hypotheses,
            spec,
            lambda sets: self.tasks("uncertainty", [ResidualTask(o) for o in sets]),
        )

    def joint_fits(
        self,
        phase: str,
        tasks: list[JointFitTask],
        hypotheses: dict[str, Hypothesis],
        beside: list | None = None,
    ) -> tuple[list[FitResult], list]:
        """Joint refits, and the results of the tasks ``beside`` them: several refits one a
        worker, in one batch with those tasks; a lone refit run here (:meth:`_joint_fit_here`),
        its Jacobians' points side by side on the workers."""
        if len(tasks) == 1:
            fit, found = self._joint_fit_here(phase, tasks[0], hypotheses, beside or [])
            return [fit], found
        found = self.tasks(phase, [*(beside or []), *tasks])
        return found[len(found) - len(tasks) :], found[: len(found) - len(tasks)]

    def _joint_fit_here(
        self,
        phase: str,
        task: JointFitTask,
        hypotheses: dict[str, Hypothesis],
        beside: list,
    ) -> tuple[FitResult, list]:
        """A joint refit run here, its training residuals on the workers: the start's in one
        batch with the tasks ``beside`` (their results come back with the fit), each trial
        point's on its own, and each Jacobian's points as one batch, side by side
        (:class:`~twin_cosim.gap.which.replay.JointProblem`: the refit a worker makes, number
        for number, its linear algebra on one BLAS thread as a worker's). The phase's fits record
        it with the totals of all its batches."""
        spec = self.pool.factory  # the workers' recipe: nominal plant, ranges, training data
        assert isinstance(spec, ReplaySpec)
        problem = JointProblem(task, spec, hypotheses)
        wall = time.perf_counter()
        totals = self.times.phases.get(phase, Phase())
        before = (totals.replays_run, totals.cache_hits, totals.cpu_s)
        first = self.tasks(phase, [ResidualTask(problem.start_overrides()), *beside])
        failure = failure_residual(first[0])
        ahead: dict[ParameterKey, np.ndarray] = {}

        def training(overrides: dict[str, float]) -> np.ndarray:
            kept = ahead.get(spec.key(overrides))
            if kept is not None:
                return kept
            return self.tasks(phase, [ResidualTask(overrides, failure)])[0]

        def jacobian_points(function: Callable, points) -> list:
            points = list(points)
            sets = [problem.overrides(u) for u in points]
            found = self.tasks(phase, [ResidualTask(o, failure) for o in sets])
            ahead.clear()  # the points of the Jacobian before are asked no more
            ahead.update((spec.key(o), r) for o, r in zip(sets, found, strict=True))
            return [function(u) for u in points]

        with threadpool_limits(limits=1, user_api="blas"):  # as in a worker (workers.py)
            fit = problem.solve(training, first[0], workers=jacobian_points)
        totals = self.times.phases[phase]
        totals.fits.append(
            {
                "fit": fit.hypothesis,
                "replays": fit.replays,
                "replays_run": totals.replays_run - before[0],
                "cache_hits": totals.cache_hits - before[1],
                "iterations": fit.iterations,
                "search_replays": fit.search_replays,
                "cpu_s": totals.cpu_s - before[2],
                "wall_s": time.perf_counter() - wall,
            }
        )
        return fit, first[1:]

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        """Calibration directions around the parameter set ``nominal + base`` (each set's
        replayed once)."""
        key = tuple(sorted(base.items()))
        if key not in self.bases:
            self.bases[key] = self._new_basis(base)
        return self.bases[key]

    def _new_basis(self, base: dict[str, float]) -> CalibrationBasis:
        moves = calibration_moves(self.nominal, base, self.calibrated, self.tolerance)
        started = None
        if not base and self.nominal_directions is not None:
            started, self.nominal_directions = self.nominal_directions, None
            if started.tasks != moves:  # not this twin's: replayed here instead
                started.cancel()
                started = None
        replays = self.tasks("calibration_directions", moves, started)
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
        left_vector = self.judging.vector(self.judging.residuals(calibrated))
        step_left = float(np.linalg.norm(left_vector))
        best, best_replays = floor, calibrated
        for _ in range(REFINEMENTS):
            scale = 1.0 + step * self.tolerance
            corrected = self.corrected(base, dict(zip(self.calibrated, step, strict=True)))
            delta, _ = self.basis(corrected).correction(
                left_vector,
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
            left_vector = self.judging.vector(self.judging.residuals(calibrated))
            left = float(np.linalg.norm(left_vector))
            if left < best.left:
                explained = math.sqrt(max(floor.before**2 - left**2, 0.0))
                best = CalibrationFloor(floor.before, left, explained, trial.coefficients)
                best_replays = calibrated
            if left >= threshold and left <= step_left * (1.0 - REFINEMENT_GAIN):
                step_left = left
                continue
            break
        return best, best_replays

    def corrected(self, base: dict[str, float], coefficients: dict[str, float]) -> dict[str, float]:
        """``base`` with the calibration correction ``coefficients`` (tolerances) applied."""
        current = {**self.nominal, **base}
        return {
            **base,
            **{n: current[n] * (1.0 + a * self.tolerance) for n, a in coefficients.items()},
        }

    def calibrated_replay(self, base: dict[str, float], floor: CalibrationFloor) -> Replays:
        """Replays with the best calibration correction applied to the calibrated parameters."""
        corrected = self.corrected(base, floor.coefficients)
        return self.tasks("calibrated_replays", [SimulateTask(corrected)])[0]
