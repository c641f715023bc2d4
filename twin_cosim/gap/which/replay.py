"""Replays of a scenario on the twin, and hypothesis fits on them, done by pool workers.

A :class:`ReplaySpec` (the scenarios, numbers and the training data: it pickles) builds a
:class:`Replayer` once per worker process: one plant instance, reset for every replay. A
:class:`JudgingSpec` (no training data) builds a :class:`JudgingReplayer`, which replays the
judging scenarios alone: the replays started before the noise floors are known. Tasks:

- :class:`SimulateTask`: replay the judging scenarios (the training scenario first when asked)
  with some FMU parameters; returns the records;
- :class:`FitTask`: fit one hypothesis on the training data (scipy least_squares on replays, or a
  scan of discrete values) on top of already accepted effects;
- :class:`JointFitTask`: refit accepted effects together with the calibrated parameters.

Each result comes back with the CPU and wall time the task took and the replays a cache
answered (:class:`Timed`).

A worker keeps the training residuals of the parameter sets it replayed last (up to
:data:`TRAINING_CACHE_BYTES`), keyed by the exact FMU parameters a replay runs with
(:func:`parameter_key`: nominal plus overrides, clipped into their ranges): a replay is
deterministic, so a parameter set asked for again (the base model every fit of a round starts
from, a least-squares fit's start that its global search evaluated, the model a joint refit
starts from, proposals clipped to the same FMU parameters) is not run again, and the residual
is the same array a fresh replay gives.

The fit minimises the normalised training residual: position residual / sigma_x and current
residual / sigma_i (sigma: the noise floors), over the training samples only; a replay for the
fit stops at the end of the training window. For an open-loop run the second signal is the motor
speed (:attr:`TrainingData.compared`), whose floor sigma_i then is in rad/s.

SciPy's optimizers are imported where a fit runs: a worker that only replays (a diagnosis whose
gap is not significant asks for nothing else) starts without SciPy, half the CPU of its start.

Every parameter set is clipped into the FMU's variable ranges before it reaches the FMU, so that
nothing derived from data can be refused by the plant; a replay that fails anyway scores ten
times the residual of the fit's starting point (at least 1e3 per sample), never better than a
valid fit.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.cosim import RunAborted, run_scenario
from twin_cosim.gap.data.residuals import anchored
from twin_cosim.gap.floors.evidence import EFFECTIVE_SAMPLE_SPACING_S
from twin_cosim.plant import Plant, PlantError
from twin_cosim.plant_model import Hypothesis, plant_model
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario

FIT_EVALUATIONS = 10  # residual evaluations per least_squares polish (plus its Jacobians)
JOINT_EVALUATIONS = 5  # residual evaluations of a joint refit (each with its Jacobian)
FIT_STEP = 0.02  # finite-difference step, as a fraction of each parameter's range
GLOBAL_POPULATION_PER_PARAMETER = 8
# Generations of the global search after its first population: from the start values (round 1)
# and from the previous round's fit (later rounds: the start is already near a valley).
GLOBAL_GENERATIONS = 3
WARM_GENERATIONS = 1
# A cold refit of a level and a shape parameter (on a log scale) profiles over the shape: the
# level fitted at PROFILE_POINTS shape values evenly spaced on the fit's unit scale, with
# PROFILE_EVALUATIONS residual evaluations each (plus their Jacobians).
PROFILE_POINTS = 12
PROFILE_EVALUATIONS = 3
UNCERTAINTY_DRAWS = 400  # draws of a model's parameters that give its FMU parameters' intervals
FAILURE_FACTOR = 10.0  # a failed replay's residual, relative to the fit's starting residual
FAILURE_FLOOR = 1e3  # least normalised residual per sample of a failed replay
# Bytes of training residuals a worker keeps: 160 of the 6.2 s training half of
# scenarios/diagnosis.yaml (0.4 MB each), more than the replays of one fit, so that the base
# model every fit of a round starts from stays in while the fits run.
TRAINING_CACHE_BYTES = 64 * 2**20

ParameterKey = tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class Timed:
    """A pool task's result, the CPU and wall time (s) the worker spent on it, the replays it
    ran and the replays its cache answered."""

    result: Any
    cpu_s: float
    wall_s: float = 0.0
    replays_run: int = 0
    cache_hits: int = 0


def bounded(hypothesis: Hypothesis, ranges: dict[str, tuple[float, float]]) -> Hypothesis:
    """The hypothesis with the bounds of parameters that are FMU parameters narrowed to their
    ranges in the variable table (the start value moved inside when needed)."""
    parameters = []
    for p in hypothesis.parameters:
        if p.name in ranges:
            low, high = max(p.lower, ranges[p.name][0]), min(p.upper, ranges[p.name][1])
            p = dataclasses.replace(
                p, lower=low, upper=high, initial=min(max(p.initial, low), high)
            )
        parameters.append(p)
    return dataclasses.replace(hypothesis, parameters=tuple(parameters))


def clipped(
    overrides: dict[str, float], ranges: dict[str, tuple[float, float]]
) -> dict[str, float]:
    """FMU parameters clipped into their (min, max) ranges of the variable table."""
    result = {}
    for name, value in overrides.items():
        low, high = ranges.get(name, (-np.inf, np.inf))
        result[name] = float(min(max(value, low), high))
    return result


def parameter_key(
    overrides: dict[str, float],
    nominal: dict[str, float],
    ranges: dict[str, tuple[float, float]],
) -> ParameterKey:
    """The FMU parameters a replay with ``overrides`` runs with (``nominal`` plus the overrides,
    clipped into their ``ranges``), sorted by name: two override sets of the same key give the
    same replay of a scenario."""
    return tuple(sorted(clipped({**nominal, **overrides}, ranges).items()))


@dataclass(frozen=True)
class TrainingData:
    """Training samples of the measured runs.

    Attributes
    ----------
    t, x, current : list of numpy.ndarray
        Per run: sample times (s), measured position (m), the measured second signal
        (``compared``: the current, A; the motor speed of an open-loop run, rad/s).
    scenario_of_run : list of int
        Per run: the index of the training scenario it follows.
    sigma_x, sigma_i : float
        Noise floors used to normalise the position (m) and second signal's residuals.
    end : float
        End of the training window, s.
    compared : str
        The record's column the second signal is compared with.
    anchors : list of numpy.ndarray or None
        Per run of an open-loop diagnosis: the samples from which its position residual counts
        (the starts of its drive's levels, :func:`twin_cosim.gap.data.residuals.anchored`);
        None in closed loop.
    """

    t: list[np.ndarray]
    x: list[np.ndarray]
    current: list[np.ndarray]
    scenario_of_run: list[int]
    sigma_x: float
    sigma_i: float
    end: float
    compared: str = "current"
    anchors: list[np.ndarray] | None = None


def cut(scenario: Scenario, end: float) -> Scenario:
    """The scenario up to ``end`` (s): reference, disturbance and open-loop signals."""
    grid = scenario.reference
    keep = grid.time <= end + 1e-12
    if keep.all():
        return scenario
    return dataclasses.replace(
        scenario,
        reference=ReferenceGrid(
            grid.period, grid.position[keep], grid.velocity[keep], grid.acceleration[keep]
        ),
        disturbance=None if scenario.disturbance is None else scenario.disturbance[keep],
        command_disturbance=(
            None if scenario.command_disturbance is None else scenario.command_disturbance[keep]
        ),
        open_loop=None if scenario.open_loop is None else scenario.open_loop[keep],
    )


def normalised_residual(records: list[RunRecord], data: TrainingData) -> np.ndarray:
    """Position and second-signal residuals of every run over its samples, normalised by the
    floors; each run against the record of the training scenario it follows."""
    parts = []
    for n, (t, x, current, k) in enumerate(
        zip(data.t, data.x, data.current, data.scenario_of_run, strict=True)
    ):
        t_sim, x_sim, i_sim = records[k]["t"], records[k]["x"], records[k][data.compared]
        position = x - np.interp(t, t_sim, x_sim)
        if data.anchors is not None:
            position = anchored(position, data.anchors[n])
        parts.append(position / data.sigma_x)
        parts.append((current - np.interp(t, t_sim, i_sim)) / data.sigma_i)
    return np.concatenate(parts)


@dataclass(frozen=True)
class Replays:
    """Records of one parameter set: each training scenario's (when asked) and each judging
    scenario's, in the order of :attr:`ReplaySpec.training_scenarios` and
    :attr:`ReplaySpec.judging`."""

    training: list[RunRecord] | None
    judging: list[RunRecord]


@dataclass(frozen=True)
class SimulateTask:
    """Replay the judging scenarios with these FMU parameters (on top of the nominal).

    ``with_training``: also the training scenarios' replays (a judging scenario's replay when
    it is the same scenario, as for a time split).
    """

    overrides: dict[str, float]
    with_training: bool = False


@dataclass(frozen=True)
class FitTask:
    """Fit one hypothesis on top of ``base`` (the accepted effects' FMU parameters).

    ``context`` holds data-derived settings of the hypotheses (orders of periodic effects,
    encoder resolution).
    """

    hypothesis: str
    base: dict[str, float]
    context: dict[str, float]
    start: tuple[float, ...] | None = None  # the previous round's fit (physical units)
    profile: bool = False  # a level and a shape parameter: start from the shape's profile
    search: bool = True  # False: the local fit alone, from the start (a round's screen)


@dataclass(frozen=True)
class JointFitTask:
    """Refit accepted effects together with the calibrated parameters, each effect on top of the
    FMU parameters of those before it.

    ``start`` holds each hypothesis' fitted values (physical units) and ``contexts`` its
    data-derived settings; scanned hypotheses keep their values, the others are refitted
    together by least squares from ``start``. Each of ``calibrated`` moves by a factor
    (1 + a tolerance) under a Gaussian prior of width the tolerance (calibration error is a
    nuisance the training data may correct, at a price): the cost is the mean squared normalised
    training residual plus |a|^2 over the training's independent samples.
    """

    hypotheses: tuple[str, ...]
    start: tuple[tuple[float, ...], ...]
    contexts: tuple[dict[str, float], ...]
    calibrated: tuple[str, ...] = ()
    tolerance: float = 0.0


@dataclass(frozen=True)
class ResidualTask:
    """The normalised training residual of one parameter set (FMU parameters on top of the
    nominal): a point of a fit or a Jacobian the parent runs on several workers' replays.
    ``failure``: what a failed replay scores per sample (the fit's :func:`failure_residual`)."""

    overrides: dict[str, float]
    failure: float = FAILURE_FLOOR


@dataclass(frozen=True)
class UncertaintyTask:
    """What the training data leave uncertain in a model: its accepted effects (``hypotheses``
    fitted at ``values``, physical units, with their ``contexts``) on top of the FMU parameters
    ``base``, with the ``calibrated`` parameters under their prior (a Gaussian of width the
    ``tolerance``, relative)."""

    base: dict[str, float]
    hypotheses: tuple[str, ...]
    values: tuple[tuple[float, ...], ...]
    contexts: tuple[dict[str, float], ...]
    calibrated: tuple[str, ...]
    tolerance: float


@dataclass(frozen=True)
class Uncertainty:
    """The linearised uncertainty of a model's parameters (:func:`linearised_uncertainty`).

    Attributes
    ----------
    names : tuple of str
        ``effect.parameter`` of the accepted effects' continuous parameters, then
        ``calibration.NAME`` of the calibrated parameters.
    deviation : tuple of float
        Standard deviation of each: effects' parameters on the fit's unit scale (0-1 over the
        bounds, log where the fit is), calibrated parameters in tolerances.
    residual_variance : float
        Mean squared normalised training residual of the model (>= 1: noise at the floors),
        which scales the deviations.
    intervals : dict
        Per FMU parameter the model sets (the effects' and the calibrated ones), the central
        95 % of its values over draws of the parameters from their linearised distribution:
        (low, high) in the variable table's units.
    """

    names: tuple[str, ...]
    deviation: tuple[float, ...]
    residual_variance: float
    intervals: dict[str, tuple[float, float]]


@dataclass(frozen=True)
class FitResult:
    """Outcome of a fit: fitted values by name, the FMU parameters, the training cost."""

    hypothesis: str
    values: dict[str, float]
    overrides: dict[str, float]
    train_cost: float
    replays: int
    message: str
    iterations: int = 0  # of the local least-squares fit (one Jacobian each)
    search_replays: int = 0  # of the start's search (global search, profile) or the scan


@dataclass(frozen=True)
class JudgingSpec:
    """Recipe of a worker that replays the judging scenarios alone (:class:`SimulateTask`
    without training): the replays a diagnosis starts before its noise floors, and so its
    :class:`ReplaySpec`, are known.

    Attributes
    ----------
    judging : list of Scenario
        The distinct scenarios the held-out runs follow.
    fmu : str
        Plant FMU.
    nominal : dict
        Nominal FMU parameters of the twin.
    ranges : dict
        (min, max) of every FMU parameter, from the variable table.
    """

    judging: list[Scenario]
    fmu: str
    nominal: dict[str, float]
    ranges: dict[str, tuple[float, float]]

    def build(self) -> JudgingReplayer:
        """The worker."""
        return JudgingReplayer(self)


@dataclass(frozen=True)
class ReplaySpec:
    """Recipe of a replay worker.

    Attributes
    ----------
    training_scenarios : list of Scenario
        The distinct scenarios the training runs follow (the scenario itself, or, for a scenario
        whose reference comes from a measured file, each run's own reference and disturbance).
    judging : list of Scenario
        The distinct scenarios the held-out runs follow (the training scenarios themselves for a
        time split).
    fmu : str
        Plant FMU.
    nominal : dict
        Nominal FMU parameters of the twin (start values, the scenario's, the identified noise).
    training : TrainingData
        What the fits see.
    model : str
        The FMU's model identifier, which selects the hypothesis library.
    ranges : dict
        (min, max) of every FMU parameter, from the variable table.
    cache_bytes : int
        Bytes of training residuals a worker keeps by parameter set, the latest first (0: none
        kept).
    """

    training_scenarios: list[Scenario]
    judging: list[Scenario]
    fmu: str
    nominal: dict[str, float]
    training: TrainingData
    model: str
    ranges: dict[str, tuple[float, float]]
    cache_bytes: int = TRAINING_CACHE_BYTES

    def key(self, overrides: dict[str, float]) -> ParameterKey:
        """The parameter set a replay with ``overrides`` runs with (:func:`parameter_key`)."""
        return parameter_key(overrides, self.nominal, self.ranges)

    def training_records(self, records: list[RunRecord]) -> list[RunRecord]:
        """The training scenarios' replays ``records`` as a worker's training replays end: at
        the last reference sample of the training window (:func:`cut`), a row a whole run's
        replay goes on beyond (a residual interpolates there)."""
        return [
            record.rows(slice(0, int(np.searchsorted(record["t"], end))))
            for record, end in zip(records, self._training_ends, strict=True)
        ]

    @cached_property
    def _training_ends(self) -> list[float]:
        """Per training scenario, where its training replay's record ends, s: half a sample
        past the last reference sample of the training window (:func:`cut`)."""
        ends = []
        for scenario in self.training_scenarios:
            grid = cut(scenario, self.training.end).reference
            ends.append(float(grid.time[-1]) + 0.5 * grid.period)
        return ends

    def training_in_judging(self) -> list[int] | None:
        """Per training scenario the index of the same judging scenario (a time split), or None
        when a training scenario is replayed on its own."""
        same = [
            next((i for i, j in enumerate(self.judging) if j is t), None)
            for t in self.training_scenarios
        ]
        return None if None in same else same  # type: ignore[return-value]

    def build(self) -> Replayer:
        """The worker."""
        return Replayer(self)


def failure_residual(start: np.ndarray) -> float:
    """What a failed replay scores per sample in a fit whose start left the normalised training
    residual ``start``: :data:`FAILURE_FACTOR` times its RMS, at least :data:`FAILURE_FLOOR`."""
    return max(FAILURE_FLOOR, FAILURE_FACTOR * float(np.sqrt(np.mean(start**2))))


class JointProblem:
    """A :class:`JointFitTask` as a least-squares problem on the fits' unit scale: the
    continuous effects' parameters (0-1 over their bounds) and the calibrated parameters' moves
    (in tolerances, -1 to 1), the parameter sets they run with, the training residual with the
    calibrated parameters' prior appended, and the solve (:meth:`solve`), run alike in a worker
    and, its residuals on the workers side by side, in the parent
    (:meth:`~twin_cosim.gap.which.replay_pool.ReplayPool.joint_fits`).
    """

    def __init__(
        self, task: JointFitTask, spec: ReplaySpec, library: dict[str, Hypothesis]
    ) -> None:
        self.task = task
        self.spec = spec
        self.hypotheses = [bounded(library[n], spec.ranges) for n in task.hypotheses]
        self.free = [h.kind == "continuous" for h in self.hypotheses]
        self.starts = [np.array(v, dtype=float) for v in task.start]
        self.effect_count = sum(
            len(s) for s, fitted in zip(self.starts, self.free, strict=True) if fitted
        )
        self.samples = sum(2 * len(t) for t in spec.training.t)
        seconds = sum(float(t[-1] - t[0]) for t in spec.training.t)
        self.prior = math.sqrt(self.samples / max(seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0))
        self.u0 = np.concatenate(
            [
                np.clip([p.to_unit(x) for p, x in zip(h.parameters, s, strict=True)], 0.0, 1.0)
                for h, s, fitted in zip(self.hypotheses, self.starts, self.free, strict=True)
                if fitted
            ]
            + [np.zeros(len(task.calibrated))]
        )

    def values_of(self, u: np.ndarray) -> list[np.ndarray]:
        """Each hypothesis' values (physical units) at the point ``u``."""
        values, at = [], 0
        for h, start, fitted in zip(self.hypotheses, self.starts, self.free, strict=True):
            if fitted:
                values.append(h.from_unit(u[at : at + len(start)]))
                at += len(start)
            else:
                values.append(start)
        return values

    def overrides_of(self, values: list[np.ndarray], a: np.ndarray) -> dict[str, float]:
        """FMU parameters of the hypotheses at ``values`` with the calibrated parameters moved
        by ``a`` tolerances."""
        task = self.task
        overrides = {
            name: self.spec.nominal[name] * (1.0 + a_j * task.tolerance)
            for name, a_j in zip(task.calibrated, a, strict=True)
        }
        for h, v, context in zip(self.hypotheses, values, task.contexts, strict=True):
            overrides |= h.to_plant(v, {**self.spec.nominal, **overrides}, context)
        return overrides

    def start_overrides(self) -> dict[str, float]:
        """FMU parameters of the start: the hypotheses' start values, nothing moved."""
        return self.overrides_of(self.starts, np.zeros(len(self.task.calibrated)))

    def overrides(self, u: np.ndarray) -> dict[str, float]:
        """FMU parameters of the point ``u``."""
        return self.overrides_of(self.values_of(u), u[self.effect_count :])

    def residual(self, training: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The point's cost vector: its normalised training residual ``training``, then the
        calibrated parameters' prior."""
        return np.concatenate([training, self.prior * u[self.effect_count :]])

    def solve(
        self,
        training_residual: Callable[[dict[str, float]], np.ndarray],
        start: np.ndarray,
        workers: Callable | None = None,
    ) -> FitResult:
        """The refit: scipy least squares from the start (its residual ``start``), each point's
        training residual from ``training_residual`` (FMU parameters on top of the nominal),
        the Jacobian's points through the map-like ``workers`` (scipy's; None: one by one);
        the start kept when nothing beats it."""
        from scipy.optimize import least_squares  # where a fit runs (module docstring)

        task = self.task
        best, cost, replays, message = self.u0, float(np.mean(start**2)), 1, "nothing to refit"
        iterations = 0
        if len(self.u0):
            lower = np.r_[np.zeros(self.effect_count), -np.ones(len(task.calibrated))]
            solution = least_squares(
                lambda u: self.residual(training_residual(self.overrides(u)), u),
                self.u0,
                bounds=(lower, np.ones(len(self.u0))),
                diff_step=FIT_STEP,
                max_nfev=JOINT_EVALUATIONS,
                x_scale=1.0,
                workers=workers,
            )
            found = float(np.sum(solution.fun**2)) / self.samples
            if found < cost:
                best, cost = solution.x, found
            replays += int(solution.nfev + (solution.njev or 0) * len(self.u0))
            message = solution.message
            iterations = int(solution.njev or 0)
        values = self.values_of(best)
        return FitResult(
            "+".join(task.hypotheses),
            {
                f"{h.name}.{name}": value
                for h, v in zip(self.hypotheses, values, strict=True)
                for name, value in h.named(v).items()
            }
            | {
                f"calibration.{n}": float(a)
                for n, a in zip(task.calibrated, best[self.effect_count :], strict=True)
            },
            clipped(self.overrides_of(values, best[self.effect_count :]), self.spec.ranges),
            cost,
            replays,
            message,
            iterations=iterations,
        )


class JudgingReplayer:
    """Replays of the judging scenarios on one plant instance (:class:`JudgingSpec`)."""

    def __init__(self, spec: JudgingSpec | ReplaySpec) -> None:
        self.spec = spec
        self.plant = Plant(Path(spec.fmu))
        self.cache_hits = 0  # training replays answered by the cache, over the worker's life
        self.replays_run = 0  # replays run, over the worker's life

    def replay(self, scenario: Scenario, overrides: dict[str, float]) -> RunRecord:
        """One scenario replayed with nominal plus ``overrides`` (clipped into their ranges)."""
        parameters = clipped({**self.spec.nominal, **overrides}, self.spec.ranges)
        self.replays_run += 1
        return run_scenario(self.plant, scenario, plant_overrides=parameters)

    def simulate(self, task: SimulateTask) -> Replays:
        """The judging scenarios' replays."""
        if task.with_training:
            raise ValueError("a replay of the training scenarios needs a ReplaySpec's worker")
        return Replays(None, [self.replay(s, task.overrides) for s in self.spec.judging])

    def answer(self, task: Any) -> Any:
        """The task's result."""
        if not isinstance(task, SimulateTask):
            raise TypeError(f"a judging replayer runs SimulateTask only, not {type(task).__name__}")
        return self.simulate(task)

    def __call__(self, task: Any) -> Timed:
        """The task's result, the CPU and wall time it took, the replays it ran and those the
        cache answered."""
        start, wall = time.process_time(), time.perf_counter()
        run, hits = self.replays_run, self.cache_hits
        result = self.answer(task)
        return Timed(
            result,
            time.process_time() - start,
            time.perf_counter() - wall,
            self.replays_run - run,
            self.cache_hits - hits,
        )

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


class Replayer(JudgingReplayer):
    """Replays and fits on one plant instance."""

    spec: ReplaySpec

    def __init__(self, spec: ReplaySpec) -> None:
        super().__init__(spec)
        self.hypotheses = {h.name: h for h in plant_model(spec.model).hypotheses}
        self.failure_residual = FAILURE_FLOOR
        self.training_cut = [cut(s, spec.training.end) for s in spec.training_scenarios]
        self.residuals: OrderedDict[ParameterKey, np.ndarray] = OrderedDict()

    def simulate(self, task: SimulateTask) -> Replays:
        """The judging scenarios' replays (and the training scenario's when asked)."""
        judging = [self.replay(s, task.overrides) for s in self.spec.judging]
        training = None
        if task.with_training:
            training = []
            for scenario in self.spec.training_scenarios:
                same = [i for i, j in enumerate(self.spec.judging) if j is scenario]
                training.append(judging[same[0]] if same else self.replay(scenario, task.overrides))
        return Replays(training, judging)

    def training_residual(self, overrides: dict[str, float]) -> np.ndarray:
        """Normalised training residual; a failed replay scores a large constant residual (the
        fit's own, never kept). A parameter set replayed lately is answered from the cache."""
        key = self.spec.key(overrides) if self.spec.cache_bytes else None
        kept = self.residuals.get(key) if key is not None else None
        if kept is not None:
            self.residuals.move_to_end(key)
            self.cache_hits += len(self.training_cut)
            return kept.copy()
        try:
            records = [self.replay(s, overrides) for s in self.training_cut]
        except (RunAborted, PlantError):
            n = sum(2 * len(t) for t in self.spec.training.t)
            return np.full(n, self.failure_residual)
        residual = normalised_residual(records, self.spec.training)
        if key is not None:
            self.residuals[key] = residual.copy()
            while sum(r.nbytes for r in self.residuals.values()) > self.spec.cache_bytes:
                self.residuals.popitem(last=False)
        return residual

    def answer(self, task: SimulateTask | FitTask | JointFitTask | ResidualTask) -> Any:
        """The task's result."""
        if isinstance(task, SimulateTask):
            return self.simulate(task)
        if isinstance(task, JointFitTask):
            return self.joint_fit(task)
        if isinstance(task, ResidualTask):
            self.failure_residual = task.failure
            return self.training_residual(task.overrides)
        return self.fit(task)

    def joint_fit(self, task: JointFitTask) -> FitResult:
        """Refit several hypotheses together (values by ``hypothesis.parameter``)."""
        problem = JointProblem(task, self.spec, self.hypotheses)
        start = self.training_residual(problem.start_overrides())
        self.failure_residual = failure_residual(start)
        return problem.solve(self.training_residual, start)

    def fit(self, task: FitTask) -> FitResult:
        """Fit a hypothesis by least squares on replays, or by scanning its discrete values."""
        from scipy.optimize import least_squares  # where a fit runs (module docstring)

        hypothesis = bounded(self.hypotheses[task.hypothesis], self.spec.ranges)
        nominal = {**self.spec.nominal, **task.base}

        def overrides_of(values: np.ndarray) -> dict[str, float]:
            return {**task.base, **hypothesis.to_plant(values, nominal, task.context)}

        def cost(values: np.ndarray) -> float:
            residual = self.training_residual(overrides_of(values))
            return float(np.mean(residual**2))

        self.failure_residual = failure_residual(self.training_residual(dict(task.base)))

        if hypothesis.kind == "scan":
            candidates = hypothesis.scan_values(task.context)
            if not candidates:
                return FitResult(task.hypothesis, {}, {}, float("inf"), 0, "no candidate value")
            costs = [cost(values) for values in candidates]
            best = candidates[int(np.argmin(costs))]
            return FitResult(
                task.hypothesis,
                hypothesis.named(best),
                clipped(overrides_of(best), self.spec.ranges),
                min(costs),
                len(candidates),
                f"scanned {len(candidates)} values",
                search_replays=len(candidates),
            )

        def residual_of_unit(u: np.ndarray) -> np.ndarray:
            return self.training_residual(overrides_of(hypothesis.from_unit(u)))

        if not task.search:
            u0, grid_replays = start_unit(hypothesis, task.start)[0], 0
        elif task.profile and shape_index(hypothesis) is not None:
            u0, grid_replays = profile_start(hypothesis, residual_of_unit)
        else:
            u0, grid_replays = self._coarse_start(hypothesis, residual_of_unit, task.start)
        solution = least_squares(
            residual_of_unit,
            u0,
            bounds=(0.0, 1.0),
            diff_step=FIT_STEP,
            max_nfev=FIT_EVALUATIONS,
            x_scale=1.0,
        )
        values = hypothesis.from_unit(solution.x)
        train_cost = float(np.mean(solution.fun**2))
        replays = grid_replays + int(solution.nfev + (solution.njev or 0) * len(u0))
        return FitResult(
            task.hypothesis,
            hypothesis.named(values),
            clipped(overrides_of(values), self.spec.ranges),
            train_cost,
            replays,
            solution.message,
            iterations=int(solution.njev or 0),
            search_replays=grid_replays,
        )

    @staticmethod
    def _coarse_start(
        hypothesis: Hypothesis, residual_of_unit, previous: tuple[float, ...] | None
    ) -> tuple[np.ndarray, int]:
        """Start of the local fit: a small global search for one or two parameters.

        Stick-slip and backlash make the training cost rough, with narrow valleys (a Stribeck
        level 2 % off can cost ten times the optimum), so a local fit from one start stalls. For
        one or two parameters scipy's differential evolution (seeded, no polish; a population of
        GLOBAL_POPULATION_PER_PARAMETER per parameter, holding the start values, and
        GLOBAL_GENERATIONS generations) picks the start of least_squares. With the previous
        round's fit (``previous``, physical units) the population holds it instead and evolves
        WARM_GENERATIONS generations: the accepted effects moved the valley, they seldom remove
        it. Three-parameter hypotheses (the nearly linear lead error) start from the previous
        fit or their start values.
        """
        from scipy.optimize import differential_evolution  # where a fit runs (module docstring)

        start, warm = start_unit(hypothesis, previous)
        generations = WARM_GENERATIONS if warm else GLOBAL_GENERATIONS
        if not searches(hypothesis):
            return start, 0
        count = 0

        def cost(u: np.ndarray) -> float:
            nonlocal count
            count += 1
            return float(np.mean(residual_of_unit(u) ** 2))

        popsize = GLOBAL_POPULATION_PER_PARAMETER
        search = differential_evolution(
            cost,
            [(0.0, 1.0)] * len(start),
            popsize=popsize,
            x0=start,
            polish=False,
            seed=0,
            maxiter=generations,
            tol=1e-3,
        )
        return np.clip(search.x, 0.0, 1.0), count


def linearised_uncertainty(
    task: UncertaintyTask,
    hypotheses: dict[str, Hypothesis],
    spec: ReplaySpec,
    residuals: Callable[[list[dict[str, float]]], list[np.ndarray]],
) -> Uncertainty:
    """The linearised uncertainty of a model's parameters on the training data.

    The training residual r is differentiated (central differences, one replay each way)
    with respect to each continuous parameter of the accepted effects (steps of
    :data:`FIT_STEP` on the fit's unit scale) and each calibrated parameter (a step of one
    tolerance). Residual samples are correlated in time, so the information is that of
    one independent sample per :data:`EFFECTIVE_SAMPLE_SPACING_S`: I = (n_eff / n) J^T J /
    s^2 plus the calibrated parameters' prior (1 per tolerance^2), s^2 the mean squared
    residual (at least 1, the noise at the floors: a model that leaves a structured gap
    knows its parameters less well). The covariance is I's pseudo-inverse. Draws of the
    parameters from that Gaussian (seeded, clipped into their bounds), each mapped to the
    FMU parameters as the model maps its fit, give each FMU parameter's central 95 %.

    Parameters
    ----------
    task
        The model and its calibrated parameters.
    hypotheses
        The effect library by name.
    spec
        The replays' recipe (nominal parameters, ranges, training data).
    residuals
        The normalised training residuals of parameter sets (FMU parameters on top of the
        nominal), in their order: the model's and both sides of every column, asked at once
        (the pool runs them side by side).
    """
    bounded_hypotheses = [bounded(hypotheses[n], spec.ranges) for n in task.hypotheses]
    sets = {name for h in bounded_hypotheses for name in h.sets}
    plain = {k: v for k, v in task.base.items() if k not in sets}
    starts = [np.array(v, dtype=float) for v in task.values]
    nominal = {
        **spec.nominal,
        **plain,
        **_beneath_effects(task, bounded_hypotheses, starts, {**spec.nominal, **plain}, spec),
    }
    free = [h.kind == "continuous" for h in bounded_hypotheses]
    unclipped = [
        np.array([p.to_unit(x) for p, x in zip(h.parameters, v, strict=True)])
        for h, v in zip(bounded_hypotheses, starts, strict=True)
    ]
    units = [np.clip(u, 0.0, 1.0) for u in unclipped]
    # An effect not moved keeps its fitted values (the parameter sets the model's replays ran
    # with), not their round trip through the unit scale, where they lie within its bounds.
    exact = [np.array_equal(u, c) for u, c in zip(unclipped, units, strict=True)]
    columns = [
        (j, k)
        for j, h in enumerate(bounded_hypotheses)
        if free[j]
        for k in range(len(h.parameters))
    ]
    count = len(columns) + len(task.calibrated)

    def overrides_of(z: np.ndarray) -> dict[str, float]:
        """FMU parameters of the coordinates z (effects' units, then tolerances)."""
        moved = {
            name: nominal[name] * (1.0 + a * task.tolerance)
            for name, a in zip(task.calibrated, z[len(columns) :], strict=True)
        }
        overrides = {**plain, **moved}
        at = 0
        for j, (h, context) in enumerate(zip(bounded_hypotheses, task.contexts, strict=True)):
            values = starts[j]
            if free[j]:
                part = z[at : at + len(values)]
                if not (exact[j] and np.array_equal(part, units[j])):  # moved: on the unit scale
                    values = h.from_unit(part)
                at += len(values)
            overrides |= h.to_plant(values, {**spec.nominal, **overrides}, context)
        return clipped(overrides, spec.ranges)

    z0 = np.concatenate(
        [units[j][k : k + 1] for j, k in columns] + [np.zeros(len(task.calibrated))]
    )
    steps = np.r_[np.full(len(columns), FIT_STEP), np.ones(len(task.calibrated))]
    sides = []
    for i, step in enumerate(steps):
        up, down = z0.copy(), z0.copy()
        up[i] += step
        down[i] -= step
        if i < len(columns):
            up[i], down[i] = min(up[i], 1.0), max(down[i], 0.0)
        sides.append((up, down))
    found = residuals([overrides_of(z0)] + [overrides_of(z) for side in sides for z in side])
    residual = found[0]
    jacobian = np.empty((len(residual), count))
    for i, (up, down) in enumerate(sides):
        r_up, r_down = found[1 + 2 * i], found[2 + 2 * i]
        jacobian[:, i] = (r_up - r_down) / max(up[i] - down[i], 1e-12)
    seconds = sum(float(t[-1] - t[0]) for t in spec.training.t)
    n_eff = 2.0 * max(seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0)  # two signals
    variance = max(float(np.mean(residual**2)), 1.0)
    prior = np.r_[np.zeros(len(columns)), np.ones(len(task.calibrated))]
    information = (n_eff / len(residual)) * (jacobian.T @ jacobian) / variance
    covariance = np.linalg.pinv(information + np.diag(prior))
    deviation = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    draws = np.random.default_rng(0).multivariate_normal(
        z0, covariance, size=UNCERTAINTY_DRAWS, method="eigh"
    )
    draws[:, : len(columns)] = np.clip(draws[:, : len(columns)], 0.0, 1.0)
    values = [overrides_of(z) for z in draws]
    changed = sorted(sets | set(task.calibrated))
    intervals = {
        name: tuple(float(q) for q in np.quantile([v[name] for v in values], [0.025, 0.975]))
        for name in changed
        if name in values[0]
    }
    names = tuple(
        f"{bounded_hypotheses[j].name}.{bounded_hypotheses[j].parameters[k].name}"
        for j, k in columns
    ) + tuple(f"calibration.{n}" for n in task.calibrated)
    return Uncertainty(names, tuple(float(d) for d in deviation), variance, intervals)


def _beneath_effects(
    task: UncertaintyTask,
    hypotheses: list[Hypothesis],
    values: list[np.ndarray],
    parameters: dict[str, float],
    spec: ReplaySpec,
) -> dict[str, float]:
    """The calibrated parameters that the model's effects set, as they stand beneath the effects
    (FMU values): those that, with the effects applied on top of ``parameters`` in their order,
    give the model's own values (``task.base``). A joint refit moves a calibrated parameter and
    an effect then sets it from the moved value (a Coulomb change adds to the Coulomb level), so
    the nominal value is not the one beneath. Each effect's formula is affine in the value beneath
    it; two evaluations invert it (a formula that does not read it keeps the nominal value)."""

    def on_top(name: str, beneath: float) -> float:
        overrides = {**parameters, name: beneath}
        for h, v, context in zip(hypotheses, values, task.contexts, strict=True):
            overrides |= h.to_plant(v, {**spec.nominal, **overrides}, context)
        return overrides[name]

    found = {}
    for name in task.calibrated:
        if name not in task.base or not any(name in h.sets for h in hypotheses):
            continue
        low = parameters[name]
        high = low * (1.0 + task.tolerance) if low else task.tolerance
        slope = (on_top(name, high) - on_top(name, low)) / (high - low)
        if slope:
            found[name] = low + (task.base[name] - on_top(name, low)) / slope
    return found


def start_unit(
    hypothesis: Hypothesis, previous: tuple[float, ...] | None
) -> tuple[np.ndarray, bool]:
    """Where a fit starts on the unit scale: the previous round's fit (``previous``, physical
    units) when there is one, else the hypothesis' start values; and whether it is the
    previous fit."""
    if previous is not None and len(previous) == len(hypothesis.parameters):
        start = [p.to_unit(v) for p, v in zip(hypothesis.parameters, previous, strict=True)]
        return np.clip(start, 0.0, 1.0), True
    return np.clip(hypothesis.initial_unit(), 0.0, 1.0), False


def searches(hypothesis: Hypothesis) -> bool:
    """Whether the fit of a hypothesis starts from a global search: a continuous one of one or
    two parameters (:meth:`Replayer._coarse_start`)."""
    return hypothesis.kind != "scan" and len(hypothesis.parameters) <= 2


def shape_index(hypothesis: Hypothesis) -> int | None:
    """Index of the shape parameter of a hypothesis of a level and a shape (the one of its two
    parameters the fit moves on a log scale, e.g. the Stribeck speed), or None."""
    logs = [i for i, p in enumerate(hypothesis.parameters) if p.log]
    if len(hypothesis.parameters) != 2 or len(logs) != 1:
        return None
    return logs[0]


def profile_start(hypothesis: Hypothesis, residual_of_unit) -> tuple[np.ndarray, int]:
    """Start of a cold fit of a level and a shape parameter: the profile over the shape.

    The training cost is rough in the shape (a Stribeck curve too wide with a level too low
    has about the right area: a valley of its own, and the global search's few generations
    can stop there), while at a given shape the level enters the residual nearly linearly. So
    the level is fitted by least squares (PROFILE_EVALUATIONS evaluations, from its start
    value) at PROFILE_POINTS shape values spread evenly on the unit (log) scale, and the
    best of these starts the local fit of both.

    Parameters
    ----------
    hypothesis
        The hypothesis (two parameters, one on a log scale: :func:`shape_index`).
    residual_of_unit
        Normalised training residual of the parameters on the unit scale.

    Returns
    -------
    numpy.ndarray, int
        The start on the unit scale and the replays the profile took.
    """
    from scipy.optimize import least_squares  # where a fit runs (module docstring)

    shape = shape_index(hypothesis)
    level = 1 - shape
    initial = np.clip(hypothesis.initial_unit(), 0.0, 1.0)
    best, replays = (math.inf, initial), 0
    for value in (np.arange(PROFILE_POINTS) + 0.5) / PROFILE_POINTS:

        def at_shape(a: np.ndarray, value: float = value) -> np.ndarray:
            u = np.empty(2)
            u[level], u[shape] = a[0], value
            return residual_of_unit(u)

        solution = least_squares(
            at_shape,
            initial[level : level + 1],
            bounds=(0.0, 1.0),
            diff_step=FIT_STEP,
            max_nfev=PROFILE_EVALUATIONS,
            x_scale=1.0,
        )
        replays += int(solution.nfev + (solution.njev or 0))
        cost = float(np.mean(solution.fun**2))
        if cost < best[0]:
            u = np.empty(2)
            u[level], u[shape] = solution.x[0], value
            best = (cost, u)
    return best[1], replays
