"""Which effect: rounds of fitting the hypotheses and judging them on held-out data.

Every round looks again at the residual the accepted effects leave: its training residual gives
the orders of the periodic hypotheses (dominant peaks of the order spectra of the motor and
screw angle, :data:`~twin_cosim.gap.effects.DEFAULT_CONTEXT` when there is none), the
hypotheses are fitted on top of the accepted effects (:mod:`twin_cosim.gap.replay`), ranked by
BIC on the training residual and judged on the held-out runs. The first round fits the whole
library; later rounds the periodic hypotheses (their orders may have changed) and the
``later_round_candidates`` best of the previous round by held-out reduction.

An effect is *accepted* when, on the held-out data,

1. the gap is significant: what the best calibration correction leaves fails the test against
   noise at the floors (:func:`twin_cosim.gap.evidence.gap_threshold`, level
   ``significance_level``), or a figure of merit (E_pk, ITAE, IAU) is off beyond what noise
   makes; calibration error alone is no gap;
2. it cuts the normalised RMS (it makes the held-out gap smaller as it stands);
3. it improves the fit beyond the noise, after the best calibration correction with and without
   it (what calibration error can explain is not the effect's to claim): its evidence z
   (:func:`twin_cosim.gap.evidence.improvement_z`) reaches the one-sided quantile of
   ``acceptance_level`` shared by the hypotheses judged in the round (Bonferroni), and it removes
   at least its fair share (1 / the library's size) of the energy above the noise; and a change
   of a calibrated parameter itself (Coulomb level, backlash, inertia, stiffness) exceeds the
   tolerance;
4. it is consistent: it makes neither the position nor the current held-out RMS worse than
   ``worsen_limit`` (1.1) times what it was, plus the noise floor (a wrong effect can trade one
   signal for the other).

The best passing effect by BIC is accepted; passing effects whose reductions differ by less
than ``group_reduction_margin`` and whose predicted changes correlate at ``group_correlation``
or more form a *group* with it (look-alikes the data cannot tell apart).

Effects that act in the same place (backlash beside Stribeck friction, a Coulomb change beside a
smaller backlash) can each make the held-out fit worse alone: each fit bends to explain the
other's part. When no single hypothesis passes a round, the ``pair_candidates`` leading ones by
training BIC are screened in pairs: the second fitted on top of the first (from its own fit of
the round), replayed on the held-out runs and judged as one candidate, with the Bonferroni
count of the round raised by the pairs tried and the fair share doubled; and each member must
earn its place in the pair: the pair against the other member's fit alone passes the evidence
and fair-share tests (:attr:`Pair.within`). The best passing pair by BIC is accepted, both
effects at once.

Effects that only pay off together: after each accepted effect, all accepted effects are refitted
together on the training data (each on top of the FMU parameters of those before it), and the
joint fit is kept when it judges better on the held-out data. When the forward rounds end, a
backward pass refits the model without each accepted effect in turn; an effect whose removal
does not hurt the held-out fit beyond the noise (its marginal evidence z below the quantile of
``acceptance_level`` shared by the accepted effects, or its marginal share of the energy above
the noise below the fair share) is dropped, the weakest first. Each kept
effect's marginal contribution in the joint model is reported.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from twin_cosim.gap.calibration import (
    CalibrationBasis,
    CalibrationFloor,
    floor_of,
    normalised_vector,
)
from twin_cosim.gap.context import DiagnosisContext, training_residuals
from twin_cosim.gap.effects import DEFAULT_CONTEXT, library_for
from twin_cosim.gap.evidence import (
    EFFECTIVE_SAMPLE_SPACING_S,
    critical_z,
    excess_share,
    fair_share,
    gap_threshold,
    improvement_z,
)
from twin_cosim.gap.floors import Floors, MetricComparison, compare_metrics, metrics_off
from twin_cosim.gap.location import dominant_order
from twin_cosim.gap.replay import FitResult, FitTask, JointFitTask, Replays, SimulateTask
from twin_cosim.gap.residuals import Residuals, residuals_of, rms
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.timing import PhaseTimes, makespan
from twin_cosim.hypotheses import Hypothesis
from twin_cosim.measured import MeasuredRun
from twin_cosim.plant_model import plant_model
from twin_cosim.reference import ReferenceGrid

Progress = Callable[[int], None]


@dataclass(frozen=True)
class Judging:
    """The held-out runs and what they are compared with.

    Attributes
    ----------
    runs : list of MeasuredRun
        Held-out runs (files or the held-out windows of a time split).
    scenario_of_run : list of int
        Per run, the index of the judging scenario it follows.
    grids : list of ReferenceGrid
        Reference of each judging scenario.
    floors : Floors
        Noise floors that normalise the residuals.
    """

    runs: list[MeasuredRun]
    scenario_of_run: list[int]
    grids: list[ReferenceGrid]
    floors: Floors

    def residuals(self, replays: Replays) -> Residuals:
        """Held-out residuals against the judging replays."""
        return residuals_of(
            self.runs,
            [replays.judging[k] for k in self.scenario_of_run],
            [self.grids[k] for k in self.scenario_of_run],
        )

    def vector(self, res: Residuals) -> np.ndarray:
        """The normalised residual vector (norm = normalised RMS)."""
        return normalised_vector(res, self.floors.sigma_position_m, self.floors.sigma_current)

    def metrics(self, replays: Replays, settings: DiagnosisSettings) -> list[MetricComparison]:
        """Measured against twin metrics (with noise) for every held-out run."""
        return [
            compare_metrics(run, replays.judging[k], self.floors, settings, seed=i)
            for i, (run, k) in enumerate(zip(self.runs, self.scenario_of_run, strict=True))
        ]

    @property
    def duration_s(self) -> float:
        """Held-out time, s (summed over the runs)."""
        return sum(float(r.t[-1] - r.t[0]) for r in self.runs)

    def significant(
        self, left: float, metrics: list[MetricComparison], settings: DiagnosisSettings
    ) -> bool:
        """Whether what the best calibration correction leaves (normalised RMS ``left``) is a
        gap: beyond noise at the floors, or a figure of merit off."""
        threshold = gap_threshold(self.duration_s, settings.significance_level)
        return left >= threshold or metrics_off(metrics)


@dataclass(frozen=True)
class Marginal:
    """What one kept effect adds to the joint model on the held-out data.

    ``evidence_z``: the evidence that the model with it fits better than the model refitted
    without it; ``excess_share``: the share of the energy above the noise it removes from the
    model without it; ``left_without`` and ``left_with``: the normalised RMS the best calibration
    correction leaves without and with it.
    """

    effect: str
    evidence_z: float
    excess_share: float
    left_without: float
    left_with: float


@dataclass
class Candidate:
    """A fitted hypothesis judged on the held-out data.

    ``holdout_rms`` and ``explained`` are normalised RMS values (1 = noise at the floors);
    ``reduction`` and ``reduction_beyond_calibration`` are fractions; ``evidence_z`` is the
    evidence of the improvement beyond the noise (:func:`~twin_cosim.gap.evidence.improvement_z`)
    and ``critical_z`` what acceptance asks of it; ``excess_share`` is the share of the energy
    above the noise it removes and ``fair_share`` what acceptance asks of it;
    ``position_rms_um`` is the held-out position gap in um and ``current_rms`` the held-out
    current gap in A (V for EMPS).
    """

    fit: FitResult
    n_parameters: int
    bic: float
    holdout_rms: float = 0.0
    reduction: float = 0.0
    reduction_beyond_calibration: float = 0.0
    evidence_z: float = 0.0
    critical_z: float = math.inf
    excess_share: float = 0.0
    fair_share: float = 1.0
    size_above_tolerance: bool = True
    consistent: bool = True
    explained: float = 0.0
    position_rms_um: float = 0.0  # um
    current_rms: float = 0.0  # A
    passes: bool = False
    change: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    replays: Replays | None = field(default=None, repr=False)

    @property
    def name(self) -> str:
        """The hypothesis' name."""
        return self.fit.hypothesis


@dataclass
class Pair(Candidate):
    """Two hypotheses fitted together (the second on top of the first) and judged as one.

    Attributes
    ----------
    members : tuple of str
        The two hypotheses, the one fitted first (better training BIC alone) first.
    member_values : tuple of tuple of float
        Each member's fitted values (physical units): the first's own fit, the second's on top.
    within : list of Marginal
        Per member, what it adds to the other member's fit alone on the held-out data.
    """

    members: tuple[str, ...] = ()
    member_values: tuple[tuple[float, ...], ...] = ()
    within: list[Marginal] = field(default_factory=list)


@dataclass
class Round:
    """One round of selection.

    Attributes
    ----------
    index : int
        1 for the first round.
    context : dict
        Data-derived settings of the hypotheses (orders, encoder resolution, dead time).
    significant : bool
        Whether the held-out gap left was significant after the best calibration correction.
    holdout_rms : float
        Normalised held-out RMS at the start of the round.
    position_rms_um, current_rms : float
        Held-out RMS of the position (um) and current (A) residuals at the start.
    calibration : CalibrationFloor
        What calibration error can explain of the held-out residual.
    metrics : list of MetricComparison
        The held-out metric comparison after the best calibration correction.
    candidates : list of Candidate
        Fitted hypotheses, best training BIC first (empty when the gap was not significant).
    accepted : list of str
        The accepted effect (with its look-alikes), the two effects of an accepted pair, or
        empty.
    pairs : list of Pair
        Pairs screened when no single hypothesis passed, best training BIC first.
    pair : Pair or None
        The accepted pair.
    """

    index: int
    context: dict[str, float]
    significant: bool
    holdout_rms: float
    position_rms_um: float
    current_rms: float
    calibration: CalibrationFloor
    metrics: list[MetricComparison]
    candidates: list[Candidate] = field(default_factory=list)
    accepted: list[str] = field(default_factory=list)
    pairs: list[Pair] = field(default_factory=list)
    pair: Pair | None = None

    @property
    def best(self) -> Candidate | None:
        """The accepted candidate (or pair)."""
        if self.pair is not None:
            return self.pair
        return next(
            (c for c in self.candidates if self.accepted and c.name == self.accepted[0]), None
        )


@dataclass(frozen=True)
class Selection:
    """The rounds, the accepted effects (after the backward pass) and their FMU parameters, the
    replays with them, the calibration floor of what they leave with its calibrated replays,
    each kept effect's marginal contribution, the effects the backward pass dropped and where
    the time went (wall s, pool tasks and replays per phase)."""

    rounds: list[Round]
    accepted: list[list[str]]
    plant_parameters: dict[str, float]
    replays: Replays
    floor: CalibrationFloor
    calibrated: Replays
    marginal: list[Marginal] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    times: dict[str, dict[str, float]] = field(default_factory=dict)


@dataclass
class _Accepted:
    """An accepted effect: its group, fitted values (physical units) and context."""

    group: list[str]
    values: tuple[float, ...]
    context: dict[str, float]

    @property
    def name(self) -> str:
        return self.group[0]


def _bic(cost: float, n_parameters: int, train_seconds: float) -> float:
    n_eff = max(train_seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0)
    return n_eff * math.log(max(cost, 1e-300)) + n_parameters * math.log(n_eff)


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) != len(b) or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(abs(np.corrcoef(a, b)[0, 1]))


def _replays_of(result: FitResult | Replays) -> int:
    """Replays a task ran: a fit's count, or one per judging scenario."""
    return result.replays if isinstance(result, FitResult) else len(result.judging)


class Selector:
    """Runs the rounds of selection on a pool of replay workers.

    Parameters
    ----------
    pool
        Pool of :class:`~twin_cosim.gap.replay.Replayer` workers.
    context : DiagnosisContext
        The runs, the plant model (hypothesis library and calibrated parameters), the gear ratio.
    nominal : dict
        Nominal FMU parameters of the twin (noise model included).
    judging : Judging
        The held-out runs.
    settings : DiagnosisSettings
    hypothesis_context : dict
        Data-derived settings of the hypotheses besides the orders (encoder resolution, nominal
        dead time).
    progress : callable or None
        Called with the number of tasks done.
    """

    def __init__(
        self,
        pool,
        context: DiagnosisContext,
        nominal: dict[str, float],
        judging: Judging,
        settings: DiagnosisSettings,
        hypothesis_context: dict[str, float],
        progress: Progress | None = None,
    ) -> None:
        self.pool = pool
        self.run_context = context
        self.library: dict[str, Hypothesis] = {h.name: h for h in library_for(context.model)}
        self.calibrated = [n for n in plant_model(context.model).calibrated if n in nominal]
        self.nominal = nominal
        self.judging = judging
        self.train_seconds = sum(float(r.t[-1] - r.t[0]) for r in context.train)
        self.settings = settings
        self.base_context = hypothesis_context
        self.progress = progress
        self.times = PhaseTimes()
        self._bases: dict[tuple, CalibrationBasis] = {}

    def _tasks(self, phase: str, tasks: list) -> list:
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

    def expected_tasks(self) -> int:
        """Pool tasks of a selection that accepts the most effects (for progress bars)."""
        per_round = 2 * len(self.calibrated) + 2
        first = len(self.settings.hypotheses or self.library)
        periodic = sum(1 for h in self.library.values() if h.periodic_in)
        later = periodic + self.settings.later_round_candidates
        rounds = self.settings.max_effects
        pairs = 2 * math.comb(self.settings.pair_candidates, 2)
        return per_round * (rounds + 1) + 2 * first + 2 * later * (rounds - 1) + pairs

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        """Calibration directions around the parameter set ``nominal + base`` (each set's
        replayed once: the joint refits and the backward pass ask for the same sets again)."""
        key = tuple(sorted(base.items()))
        if key not in self._bases:
            self._bases[key] = self._new_basis(base)
        return self._bases[key]

    def _new_basis(self, base: dict[str, float]) -> CalibrationBasis:
        tolerance = self.settings.calibration_tolerance
        current = {**self.nominal, **base}
        moves = [
            {**base, name: current[name] * (1.0 + sign * tolerance)}
            for name in self.calibrated
            for sign in (1.0, -1.0)
        ]
        replays = self._tasks("calibration_directions", [SimulateTask(m) for m in moves])
        columns = []
        for i in range(0, len(moves), 2):
            up = self.judging.vector(self.judging.residuals(replays[i]))
            down = self.judging.vector(self.judging.residuals(replays[i + 1]))
            columns.append(0.5 * (down - up))  # residual = measured - simulated
        directions = np.column_stack(columns) if columns else np.zeros((0, 0))
        return CalibrationBasis(self.calibrated, directions)

    def context(self, training_residual: Residuals) -> dict[str, float]:
        """Orders of the periodic hypotheses read off the training residual left."""
        context = dict(self.base_context)
        angle = training_residual.motor_angle
        for key, signal_angle in (
            ("motor_order", angle),
            ("screw_order", self.run_context.screw_angle(angle)),
        ):
            order = dominant_order(training_residual, training_residual.current, signal_angle)
            context[key] = order if order is not None else DEFAULT_CONTEXT[key]
        return context

    def calibrated_replay(self, base: dict[str, float], floor: CalibrationFloor) -> Replays:
        """Replays with the best calibration correction applied to the calibrated parameters."""
        current = {**self.nominal, **base}
        tolerance = self.settings.calibration_tolerance
        corrected = {
            **base,
            **{n: current[n] * (1.0 + a * tolerance) for n, a in floor.coefficients.items()},
        }
        return self._tasks("calibrated_replays", [SimulateTask(corrected)])[0]

    def run(self, start: Replays) -> Selection:
        """Forward selection with joint refits from the replays of the nominal twin, then the
        backward pass."""
        settings = self.settings
        accepted: list[_Accepted] = []
        base: dict[str, float] = {}
        replays = start
        remaining = list(settings.hypotheses or self.library)
        rounds: list[Round] = []
        starts: dict[str, tuple[float, ...]] = {}
        while remaining and len(accepted) < settings.max_effects:
            held = self.judging.residuals(replays)
            vector = self.judging.vector(held)
            basis = self.basis(base)
            floor = floor_of(basis, vector)
            calibrated = self.calibrated_replay(base, floor)
            metrics = self.judging.metrics(calibrated, settings)
            context = self.context(training_residuals(self.run_context, replays.training))
            current = Round(
                len(rounds) + 1,
                context,
                self.judging.significant(floor.left, metrics, settings),
                float(np.linalg.norm(vector)),
                held.position_rms_um(),
                held.current_rms(),
                floor,
                metrics,
            )
            rounds.append(current)
            if not current.significant:
                break
            current.candidates = self._fit_and_judge(
                remaining, base, context, held, vector, basis, starts
            )
            starts = {c.name: tuple(c.fit.values.values()) for c in current.candidates}
            passing = [c for c in current.candidates if c.passes]
            if passing:
                best: Candidate = passing[0]
                current.accepted = [best.name] + [
                    c.name
                    for c in passing[1:]
                    if abs(c.reduction - best.reduction) < settings.group_reduction_margin
                    and _correlation(c.change, best.change) >= settings.group_correlation
                ]
                found = [(list(current.accepted), tuple(best.fit.values.values()))]
            elif len(accepted) + 2 <= settings.max_effects:
                current.pairs = self._screen_pairs(
                    current, base, held, vector, basis, len(current.candidates)
                )
                pair = next((p for p in current.pairs if p.passes), None)
                if pair is None:
                    break
                best, current.pair, current.accepted = pair, pair, list(pair.members)
                found = [([n], v) for n, v in zip(pair.members, pair.member_values, strict=True)]
            else:
                break
            for group, values in found:
                for earlier in accepted:  # the data now tell it apart from an earlier look-alike
                    if group[0] in earlier.group[1:]:
                        earlier.group.remove(group[0])
                accepted.append(_Accepted(group, values, context))
            base, replays = self._joint(accepted, dict(best.fit.overrides))
            remaining = self._next_candidates(current, {g[0] for g, _ in found}, remaining)
        accepted, base, replays, marginal, dropped = self._backward(accepted, base, replays, start)
        vector = self.judging.vector(self.judging.residuals(replays))
        floor = floor_of(self.basis(base), vector)
        return Selection(
            rounds,
            [a.group for a in accepted],
            base,
            replays,
            floor,
            self.calibrated_replay(base, floor),
            marginal,
            dropped,
            self.times.as_dict(),
        )

    def _left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        """The normalised held-out residual the best calibration correction leaves."""
        vector = self.judging.vector(self.judging.residuals(replays))
        return self.basis(overrides).correction(vector)[1]

    def _refit_task(self, accepted: list[_Accepted]) -> JointFitTask:
        """The refit of effects together on the training data, with the calibrated parameters
        under their prior."""
        return JointFitTask(
            tuple(a.name for a in accepted),
            tuple(a.values for a in accepted),
            tuple(a.context for a in accepted),
            tuple(self.calibrated),
            self.settings.calibration_tolerance,
        )

    def _joint(
        self, accepted: list[_Accepted], sequential: dict[str, float]
    ) -> tuple[dict[str, float], Replays]:
        """The accepted effects' parameters: refitted together when that judges better on the
        held-out data than the sequential fit, and their replays (the sequential replay runs
        beside the refit)."""
        replays, refit = self._tasks(
            "joint_refits",
            [SimulateTask(sequential, with_training=True), self._refit_task(accepted)],
        )
        joint = refit.overrides
        joint_replays = self._tasks("joint_refits", [SimulateTask(joint, with_training=True)])[0]
        left_joint = np.linalg.norm(self._left(joint, joint_replays))
        if left_joint < np.linalg.norm(self._left(sequential, replays)):
            return joint, joint_replays
        return sequential, replays

    def _without_each(
        self, accepted: list[_Accepted], start: Replays
    ) -> list[tuple[dict[str, float], Replays]]:
        """Per accepted effect, the model refitted without it (FMU parameters, replays); the
        refits run at once. Without a single effect it is the nominal twin (``start``): the
        best calibration correction of its held-out residual gives calibration error every
        benefit of the doubt already."""
        if len(accepted) == 1:
            return [({}, start)]
        refits = self._tasks(
            "backward_pass",
            [self._refit_task(accepted[:j] + accepted[j + 1 :]) for j in range(len(accepted))],
        )
        withouts = self._tasks(
            "backward_pass", [SimulateTask(r.overrides, with_training=True) for r in refits]
        )
        return [(r.overrides, w) for r, w in zip(refits, withouts, strict=True)]

    def _backward(
        self,
        accepted: list[_Accepted],
        base: dict[str, float],
        replays: Replays,
        start: Replays,
    ) -> tuple[list[_Accepted], dict[str, float], Replays, list[Marginal], list[str]]:
        """Drop, weakest first, accepted effects whose removal does not hurt the held-out fit
        beyond the noise; the kept effects' marginal contributions. A single effect is kept: it
        passed the stricter test of its round."""
        duration, dropped = self.judging.duration_s, []
        least_share = fair_share(len(self.library))
        while accepted:
            with_all = self._left(base, replays)
            trials = []
            for j, (overrides, without) in enumerate(self._without_each(accepted, start)):
                left = self._left(overrides, without)
                z, share = improvement_z(left, with_all, duration), excess_share(left, with_all)
                strength = min(
                    z / critical_z(self.settings.acceptance_level, len(accepted)),
                    share / least_share,
                )
                marginal = Marginal(
                    accepted[j].name,
                    z,
                    share,
                    float(np.linalg.norm(left)),
                    float(np.linalg.norm(with_all)),
                )
                trials.append((strength, j, overrides, without, marginal))
            weakest = min(trials, key=lambda trial: trial[0])
            if len(accepted) == 1 or weakest[0] >= 1.0:
                return accepted, base, replays, [trial[4] for trial in trials], dropped
            _, j, base, replays, _ = weakest
            dropped.append(accepted[j].name)
            accepted = accepted[:j] + accepted[j + 1 :]
        return accepted, base, replays, [], dropped

    def _next_candidates(self, done: Round, fitted: set[str], remaining: list[str]) -> list[str]:
        """Periodic hypotheses and the best of the round by held-out reduction; a look-alike of
        the accepted effects stays a candidate (two effects at once can look alike alone)."""
        left = [n for n in remaining if n not in fitted]
        periodic = [n for n in left if self.library[n].periodic_in]
        ranked = sorted(
            (c for c in done.candidates if c.name in left and c.name not in periodic),
            key=lambda c: -c.reduction,
        )
        return periodic + [c.name for c in ranked[: self.settings.later_round_candidates]]

    def _fit_and_judge(
        self,
        names: list[str],
        base: dict[str, float],
        context: dict[str, float],
        held: Residuals,
        vector: np.ndarray,
        basis: CalibrationBasis,
        starts: dict[str, tuple[float, ...]],
    ) -> list[Candidate]:
        """Fit every hypothesis (from its fit of the round before, in ``starts``, when there
        is one), replay it on the held-out runs and judge it."""
        phase = "later_round_fits" if starts else "first_round_fits"
        fits = self._tasks(phase, [FitTask(n, base, context, starts.get(n)) for n in names])
        critical = critical_z(self.settings.acceptance_level, len(names))
        replays = self._tasks("candidate_replays", [SimulateTask(f.overrides) for f in fits])
        candidates = []
        for fit, replay in zip(fits, replays, strict=True):
            hypothesis = self.library[fit.hypothesis]
            candidate = Candidate(
                fit,
                len(hypothesis.parameters),
                _bic(fit.train_cost, len(hypothesis.parameters), self.train_seconds),
                replays=replay,
            )
            candidate.size_above_tolerance = self._size_above_tolerance(
                hypothesis, tuple(fit.values.values()), base
            )
            self._judge(candidate, held, vector, basis, critical)
            candidates.append(candidate)
        return sorted(candidates, key=lambda c: c.bic)

    def _size_above_tolerance(
        self, hypothesis: Hypothesis, values: tuple[float, ...], base: dict[str, float]
    ) -> bool:
        """Whether a change of a calibrated parameter (fitted ``values`` on top of the FMU
        parameters ``base``) exceeds the calibration tolerance; True for other effects."""
        if hypothesis.relative_size is None or not values:
            return True
        size = hypothesis.relative_size(np.array(values), {**self.nominal, **base})
        return size >= self.settings.calibration_tolerance

    def _screen_pairs(
        self,
        current: Round,
        base: dict[str, float],
        held: Residuals,
        vector: np.ndarray,
        basis: CalibrationBasis,
        singles: int,
    ) -> list[Pair]:
        """Pairs of the round's leading hypotheses by training BIC, the second fitted on top of
        the first, judged as one candidate and each member against the other alone (module
        docstring); best training BIC first.

        Parameters
        ----------
        current
            The round, its candidates fitted and judged (best training BIC first).
        base
            FMU parameters of the accepted effects.
        held, vector
            The held-out residual at the start of the round, and its normalised vector.
        basis
            Calibration directions around ``base``.
        singles
            Hypotheses judged alone in the round (for the Bonferroni count).
        """
        leaders = [c for c in current.candidates if math.isfinite(c.bic) and c.fit.values]
        couples = list(itertools.combinations(leaders[: self.settings.pair_candidates], 2))
        if not couples:
            return []
        fits = self._tasks(
            "pair_fits",
            [
                FitTask(
                    b.name, dict(a.fit.overrides), current.context, tuple(b.fit.values.values())
                )
                for a, b in couples
            ],
        )
        replays = self._tasks("pair_replays", [SimulateTask(f.overrides) for f in fits])
        critical = critical_z(self.settings.acceptance_level, singles + len(couples))
        least_share = fair_share(len(self.library))
        duration = self.judging.duration_s
        pairs = []
        for (a, b), fit, replay in zip(couples, fits, replays, strict=True):
            values = (tuple(a.fit.values.values()), tuple(fit.values.values()))
            n_parameters = a.n_parameters + b.n_parameters
            pair = Pair(
                FitResult(
                    f"{a.name}+{b.name}",
                    {f"{a.name}.{k}": v for k, v in a.fit.values.items()}
                    | {f"{b.name}.{k}": v for k, v in fit.values.items()},
                    fit.overrides,
                    fit.train_cost,
                    fit.replays,
                    fit.message,
                ),
                n_parameters,
                _bic(fit.train_cost, n_parameters, self.train_seconds),
                replays=replay,
                members=(a.name, b.name),
                member_values=values,
            )
            pair.size_above_tolerance = self._size_above_tolerance(
                self.library[a.name], values[0], base
            ) and self._size_above_tolerance(self.library[b.name], values[1], a.fit.overrides)
            self._judge(pair, held, vector, basis, critical, shares=2)
            with_both = basis.correction(self.judging.vector(self.judging.residuals(replay)))[1]
            for member, other in ((a, b), (b, a)):
                alone = self.judging.vector(self.judging.residuals(other.replays))
                without = basis.correction(alone)[1]
                z = improvement_z(without, with_both, duration)
                share = excess_share(without, with_both)
                pair.within.append(
                    Marginal(
                        member.name,
                        z,
                        share,
                        float(np.linalg.norm(without)),
                        float(np.linalg.norm(with_both)),
                    )
                )
                pair.passes = pair.passes and z >= critical and share >= least_share
            pairs.append(pair)
        return sorted(pairs, key=lambda p: p.bic)

    def _judge(
        self,
        candidate: Candidate,
        held: Residuals,
        vector: np.ndarray,
        basis: CalibrationBasis,
        critical: float,
        shares: int = 1,
    ) -> None:
        """Held-out figures and the acceptance tests of a fitted candidate (of ``shares``
        hypotheses: the fair share of the excess energy it must remove is that many times one
        hypothesis')."""
        settings = self.settings
        sigma_x, sigma_i = self.judging.floors.sigma_position_m, self.judging.floors.sigma_current
        after = self.judging.residuals(candidate.replays)
        after_vector = self.judging.vector(after)
        before_rms = float(np.linalg.norm(vector))
        candidate.holdout_rms = float(np.linalg.norm(after_vector))
        candidate.reduction = 1.0 - candidate.holdout_rms / before_rms if before_rms else 0.0
        candidate.explained = math.sqrt(max(before_rms**2 - candidate.holdout_rms**2, 0.0))
        left_without = basis.correction(vector)[1]
        left_with = basis.correction(after_vector)[1]
        without, with_ = float(np.linalg.norm(left_without)), float(np.linalg.norm(left_with))
        candidate.reduction_beyond_calibration = 1.0 - with_ / without if without > 0 else 0.0
        candidate.evidence_z = improvement_z(left_without, left_with, self.judging.duration_s)
        candidate.critical_z = critical
        candidate.excess_share = excess_share(left_without, left_with)
        candidate.fair_share = shares * fair_share(len(self.library))
        candidate.position_rms_um = after.position_rms_um()
        candidate.current_rms = after.current_rms()
        worse_x = rms(after.position) - settings.worsen_limit * rms(held.position)  # m
        worse_i = rms(after.current) - settings.worsen_limit * rms(held.current)  # A
        candidate.consistent = worse_x <= sigma_x and worse_i <= sigma_i
        candidate.change = vector - after_vector
        candidate.passes = (
            candidate.reduction > 0.0
            and candidate.evidence_z >= critical
            and candidate.excess_share >= candidate.fair_share
            and candidate.size_above_tolerance
            and candidate.consistent
        )
