"""Which effect: rounds of fitting the hypotheses and judging them on held-out data.

Every round looks again at the residual the accepted effects leave: its training residual gives
the orders of the periodic hypotheses (dominant peaks of the order spectra of the motor and
screw angle, :data:`~twin_cosim.gap.effects.DEFAULT_CONTEXT` when there is none), the
hypotheses are fitted on top of the accepted effects (:mod:`twin_cosim.gap.which.replay`), ranked by
BIC on the training residual and judged on the held-out runs. The first round fits the whole
library; later rounds the periodic hypotheses (their orders may have changed) and the
``later_round_candidates`` best of the previous round by held-out reduction.

Which hypothesis passes is :func:`twin_cosim.gap.judging.judge`'s to say (on the held-out runs,
:class:`~twin_cosim.gap.judging.Judging`). The best passing effect by BIC is accepted; passing
effects whose reductions differ by less than ``group_reduction_margin`` and whose predicted
changes correlate at ``group_correlation`` or more form a *group* with it (look-alikes the data
cannot tell apart).

When no single hypothesis passes, pairs are screened (:mod:`twin_cosim.gap.which.pairs`).
Effects that
only pay off together: after each accepted effect, all accepted effects are refitted together on
the training data (each on top of the FMU parameters of those before it), and the joint fit is
kept when it judges better on the held-out data. When the forward rounds end, each accepted
effect is refitted from a cold start on top of the others (:mod:`twin_cosim.gap.which.refresh`;
the rounds resume when a refit replaced its effect with a gain that passes a candidate's
evidence and fair-share tests, and more effects are allowed), then each
accepted effect may be swapped for a rival that passed its round (:mod:`twin_cosim.gap.which.swaps`;
the model after a swap is refitted cold in turn, and the rounds resume while more effects are
allowed). The swaps are judged against the refitted model: an effect accepted early and
fitted while later ones were missing can make a wrong rival look better than the model. The
backward pass (:mod:`twin_cosim.gap.which.backward`) then drops the effects the joint model does not
need.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from twin_cosim.gap.data.context import (
    DEFAULT_CONTEXT,
    DiagnosisContext,
    library_for,
    training_residuals,
)
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.calibration import CalibrationBasis, CalibrationFloor, floor_of
from twin_cosim.gap.floors.evidence import critical_z
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.where.location import dominant_order
from twin_cosim.gap.which.acceptance import Judging, judge
from twin_cosim.gap.which.backward import backward
from twin_cosim.gap.which.pairs import screen_pairs
from twin_cosim.gap.which.refresh import refresh
from twin_cosim.gap.which.replay import (
    FitResult,
    FitTask,
    JointFitTask,
    Replays,
    SimulateTask,
    shape_index,
)
from twin_cosim.gap.which.replay_pool import PhaseTimes, makespan
from twin_cosim.gap.which.rounds import (
    Accepted,
    Candidate,
    Refit,
    Round,
    Selection,
    Swap,
    bic,
    correlation,
)
from twin_cosim.gap.which.swaps import swap
from twin_cosim.hypotheses import Hypothesis
from twin_cosim.plant_model import plant_model

Progress = Callable[[int], None]


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

    def expected_tasks(self) -> int:
        """Pool tasks of a selection that accepts the most effects (for progress bars)."""
        per_round = 2 * len(self.calibrated) + 2
        first = len(self.settings.hypotheses or self.library)
        periodic = sum(1 for h in self.library.values() if h.periodic_in)
        later = periodic + self.settings.later_round_candidates
        rounds = self.settings.max_effects
        pairs = 2 * math.comb(self.settings.pair_candidates, 2)
        swaps = 2 * rounds  # one rival per accepted effect
        # after each accepted effect and a swap: each effect, a level-and-shape one twice
        shaped = sum(1 for h in self.library.values() if shape_index(h) is not None)
        refreshes = 2 * (rounds + min(shaped, rounds)) * (rounds + 1)
        return (
            per_round * (rounds + 1)
            + 2 * first
            + 2 * later * (rounds - 1)
            + pairs
            + refreshes
            + swaps
        )

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
        replays = self.tasks("calibration_directions", [SimulateTask(m) for m in moves])
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
        return self.tasks("calibrated_replays", [SimulateTask(corrected)])[0]

    def run(self, start: Replays) -> Selection:
        """Forward selection with joint refits from the replays of the nominal twin, cold
        refits of the accepted effects and swaps for rivals of their round (the forward rounds
        resume after a refit whose gain passes the evidence tests or a swap, while more effects
        are allowed), then the backward pass."""
        settings = self.settings
        accepted: list[Accepted] = []
        rounds: list[Round] = []
        swaps: list[Swap] = []
        refits: list[Refit] = []
        base: dict[str, float] = {}
        replays = start
        remaining = list(settings.hypotheses or self.library)
        starts: dict[str, tuple[float, ...]] = {}
        fresh = False  # the model refitted cold since it last changed
        while True:
            count = len(accepted)
            base, replays, starts = self._forward(
                accepted, rounds, base, replays, remaining, starts
            )
            fresh = fresh and len(accepted) == count
            if not fresh:
                fresh = True
                base, replays, moved = self._refreshed(accepted, base, replays, refits)
                if moved and len(accepted) < settings.max_effects:
                    remaining = self._not_accepted(accepted)
                    continue
            swapped = swap(self, rounds, accepted, base, replays, swaps)
            if swapped is None:
                break
            base, replays = swapped
            fresh = False
            if len(accepted) >= settings.max_effects:
                base, replays, _ = self._refreshed(accepted, base, replays, refits)
                break
            remaining = self._not_accepted(accepted)
        accepted, base, replays, marginal, dropped = backward(self, accepted, base, replays, start)
        vector = self.judging.vector(self.judging.residuals(replays))
        floor = floor_of(self.basis(base), vector)
        return Selection(
            rounds,
            [a.group for a in accepted],
            base,
            replays,
            floor,
            self.calibrated_replay(base, floor),
            marginal=marginal,
            dropped=dropped,
            swaps=swaps,
            refits=refits,
            times=self.times.as_dict(),
        )

    def _refreshed(
        self,
        accepted: list[Accepted],
        base: dict[str, float],
        replays: Replays,
        refits: list[Refit],
    ) -> tuple[dict[str, float], Replays, bool]:
        """The model after the cold refits (:func:`~twin_cosim.gap.refresh.refresh`: FMU
        parameters, replays), the refit that replaced its effect appended to ``refits``, and
        whether its gain passed the evidence tests (a further round may find more)."""
        refitted = refresh(self, accepted, base, replays)
        if refitted is None:
            return base, replays, False
        base, replays, record = refitted
        refits.append(record)
        return base, replays, record.significant

    def _forward(
        self,
        accepted: list[Accepted],
        rounds: list[Round],
        base: dict[str, float],
        replays: Replays,
        remaining: list[str],
        starts: dict[str, tuple[float, ...]],
    ) -> tuple[dict[str, float], Replays, dict[str, tuple[float, ...]]]:
        """Rounds of forward selection until the gap is not significant, no hypothesis (or
        pair) passes or the most effects are accepted; ``accepted`` and ``rounds`` grow in
        place. Returns the accepted effects' FMU parameters, their replays and the last
        round's fits (the starts of a later round)."""
        settings = self.settings
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
                    and correlation(c.change, best.change) >= settings.group_correlation
                ]
                found = [(list(current.accepted), tuple(best.fit.values.values()))]
            elif len(accepted) + 2 <= settings.max_effects:
                current.pairs = screen_pairs(
                    self, current, base, held, vector, basis, len(current.candidates)
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
                accepted.append(Accepted(group, values, context, current.index))
            base, replays = self.joint(accepted, dict(best.fit.overrides))
            remaining = self._next_candidates(current, {g[0] for g, _ in found}, remaining)
        return base, replays, starts

    def left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        """The normalised held-out residual the best calibration correction leaves."""
        vector = self.judging.vector(self.judging.residuals(replays))
        return self.basis(overrides).correction(vector)[1]

    def refit_task(self, accepted: list[Accepted]) -> JointFitTask:
        """The refit of effects together on the training data, with the calibrated parameters
        under their prior."""
        return JointFitTask(
            tuple(a.name for a in accepted),
            tuple(a.values for a in accepted),
            tuple(a.context for a in accepted),
            tuple(self.calibrated),
            self.settings.calibration_tolerance,
        )

    def joint(
        self, accepted: list[Accepted], sequential: dict[str, float]
    ) -> tuple[dict[str, float], Replays]:
        """The accepted effects' parameters: refitted together when that judges better on the
        held-out data than the sequential fit, and their replays (the sequential replay runs
        beside the refit)."""
        replays, refit = self.tasks(
            "joint_refits",
            [SimulateTask(sequential, with_training=True), self.refit_task(accepted)],
        )
        joint = refit.overrides
        joint_replays = self.tasks("joint_refits", [SimulateTask(joint, with_training=True)])[0]
        left_joint = np.linalg.norm(self.left(joint, joint_replays))
        if left_joint < np.linalg.norm(self.left(sequential, replays)):
            return joint, joint_replays
        return sequential, replays

    def _not_accepted(self, accepted: list[Accepted]) -> list[str]:
        """The hypotheses a resumed round fits: all but the accepted effects."""
        names = {a.name for a in accepted}
        return [n for n in (self.settings.hypotheses or self.library) if n not in names]

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
        fits = self.tasks(phase, [FitTask(n, base, context, starts.get(n)) for n in names])
        critical = critical_z(self.settings.acceptance_level, len(names))
        replays = self.tasks("candidate_replays", [SimulateTask(f.overrides) for f in fits])
        candidates = []
        for fit, replay in zip(fits, replays, strict=True):
            hypothesis = self.library[fit.hypothesis]
            candidate = Candidate(
                fit,
                len(hypothesis.parameters),
                bic(fit.train_cost, len(hypothesis.parameters), self.train_seconds),
                replays=replay,
            )
            candidate.size_above_tolerance = self.size_above_tolerance(
                hypothesis, tuple(fit.values.values()), base
            )
            judge(
                candidate,
                self.judging,
                self.settings,
                len(self.library),
                held,
                vector,
                basis,
                critical,
            )
            candidates.append(candidate)
        return sorted(candidates, key=lambda c: c.bic)

    def size_above_tolerance(
        self, hypothesis: Hypothesis, values: tuple[float, ...], base: dict[str, float]
    ) -> bool:
        """Whether a change of a calibrated parameter (fitted ``values`` on top of the FMU
        parameters ``base``) exceeds the calibration tolerance; True for other effects."""
        if hypothesis.relative_size is None or not values:
            return True
        size = hypothesis.relative_size(np.array(values), {**self.nominal, **base})
        return size >= self.settings.calibration_tolerance
