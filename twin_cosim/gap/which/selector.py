"""Which effects: the selector and the records of its steps.

:meth:`Selector.run` runs the steps in this order; each asks the acceptance rule of
:mod:`twin_cosim.gap.which.acceptance` whether a change passes, and runs its replays and fits
on the :class:`~twin_cosim.gap.which.replay_pool.ReplayPool`.

**Rounds** (:meth:`Selector.forward`). Every round looks again at the residual the accepted
effects leave: its training residual gives the orders of the periodic hypotheses (dominant peaks
of the order spectra of the motor and screw angle,
:data:`~twin_cosim.gap.data.context.DEFAULT_CONTEXT` when there is none), the hypotheses are
fitted on top of the accepted effects (:mod:`twin_cosim.gap.which.replay`), ranked by BIC on the
training residual and judged on the held-out runs
(:func:`~twin_cosim.gap.which.acceptance.judge`). The first round fits the whole library (a
screen: local fits, a level and a shape from its profile, the leaders searched); later
rounds the periodic hypotheses (their orders may have changed) and the
``later_round_candidates`` best of the previous round by held-out reduction, each from its fit
of the round before, a level and a shape from its profile too. The candidates that
pass are judged once more with the calibration corrections replayed
(:meth:`Selector.replay_corrections`; test 5 of the acceptance rule), as are the pairs below;
one that fails it does not pass (a later round then goes on to the joint screen, whose refits
are judged without a correction). The best passing effect by BIC is accepted; passing effects
whose reductions differ by less than ``group_reduction_margin`` and whose predicted changes
correlate at ``group_correlation`` or more form a *group* with it (look-alikes the data cannot
tell apart). After each accepted effect all accepted effects are refitted together on the
training data (each on top of the FMU parameters of those before it), and the joint fit is kept
when it judges better on the held-out data (:meth:`Selector.joint`).

**Pairs** (:meth:`Selector.screen_pairs`). Effects that act in the same place (backlash beside
Stribeck friction, a Coulomb change beside a smaller backlash) can each make the held-out fit
worse alone: each fit bends to explain the other's part. When no single hypothesis passes a
round and two more effects are allowed, the ``pair_candidates`` leading ones by training BIC
are screened in pairs: the second fitted on top of the first (from its own fit of the round),
replayed on the held-out runs and judged as one candidate, with the Bonferroni count of the
round raised by the pairs tried and the fair share doubled; and each member must earn its place
in the pair: the pair against the other member's fit alone passes the rule
(:attr:`~twin_cosim.gap.which.acceptance.Pair.within`). The best passing pair by BIC is
accepted, both effects at once.

**The joint screen** (:meth:`Selector.screen_joint`). An effect accepted alone can take up
part of an effect found later in the same place (a backlash change fitted 1.6 um too large
beside a missing stiffness change of +14 %), and a later hypothesis fitted on top of it then
explains too little to pass (there: +1.4 %, within the tolerance). So when no hypothesis passes
a later round on top of the accepted effects, the ``joint_candidates`` leading ones by training
BIC are refitted together with the accepted effects and the calibrated parameters under their
prior (the joint refit of :meth:`Selector.joint` with the hypothesis added, from its fit of the
round), replayed on the held-out runs and judged as candidates, the Bonferroni count of the
round raised by the refits tried. The refits moved the calibrated parameters themselves, so the
held-out residuals are judged as they are, without the calibration correction of the other
steps (it would count calibration error twice: on a random machine whose accepted effects were
fitted far off, a Stribeck curve refitted with them cut the normalised RMS by 1.8 % and what the
correction left by 13 %). They are judged against the model as it is or, when it leaves less,
against the same refit without a hypothesis: a refit moves the accepted effects further than
the model's own refit did, and that part of the gain is no candidate's. The best passing one by
training BIC is accepted with the accepted effects at their values of its refit; the pair screen
(below) comes only after it, and counts its refits among its tests.

**Cold refits** (:meth:`Selector.refresh`). An effect accepted in an early round was fitted
while the effects found later were missing, and the joint refits after each round move it only
locally (a few least-squares steps): a Stribeck curve fitted beside a missing inertia change can
stay in the wrong valley of the rough training cost for good, with about the right area under
the curve and the wrong level and width (on a transfer machine: 0.107 N.m at 0.87 rad/s for
0.160 N.m at 0.58 rad/s). So when the forward rounds end, and after a swap, each accepted effect
fitted by least squares is refitted from a search over its whole range
(:class:`~twin_cosim.gap.which.replay.FitTask` without a start: the global search of round 1,
and for a level and a shape parameter such as the Stribeck level and speed also the profile
over the shape, :func:`~twin_cosim.gap.which.replay.profile_start`: the two searches stop in
different valleys of a rough cost) on top of the others as they are now; the refit that leaves
the least after the best calibration correction on the held-out data replaces its effect when
it leaves less than the model as it is. Its gain is judged by the rule, the refits tried
sharing the level (:class:`Refit`); only a refit that passes lets the forward rounds resume
while more effects are allowed: a refit that moves a curve within the noise leaves the next
round the same candidates to judge against nearly the same residual (on the issue's
three-effect machine: one round more, 230 replays, nothing accepted).

**Swaps** (:meth:`Selector.swap`). A round accepts the best passing hypothesis by training BIC,
and an effect in the wrong place can win it: a stiffness change shifts the resonance, and a
backlash or an inertia change fitted alone takes that up first (on random tune machines: an
inertia change of +21 % fitted for a stiffness change of -35 %, one of -23 % for +35 %). Once it
is in, the right effect fitted on top of it is under the tolerance or its fair share, and the
joint refits only move the accepted effects locally. So each accepted effect is replaced in turn
by each *rival*: a hypothesis that passed every acceptance test in the round that accepted the
effect, outside its look-alike group and not accepted itself. The rival is fitted on top of the
other accepted effects (from its fit of that round), then all effects of the swapped model are
refitted together, and the better of the two on the held-out data is judged against the model as
it is with the tests of a round's candidates, the Bonferroni count being the swaps tried (tests
1-4 of :func:`~twin_cosim.gap.which.acceptance.judge`: the swapped model's calibrated parameters
were refitted). The best passing swap by training BIC is made; an effect swapped out is never
swapped back in. The swaps come after the cold refits: an effect accepted early and fitted while
later ones were missing can make a wrong rival look better than the model. The model after a
swap is refitted cold in turn, and the rounds resume while more effects are allowed.

**The backward pass** (:meth:`Selector.backward`) refits the model without each accepted effect
in turn (the refits at once; without a single effect the model is the nominal twin) and drops,
weakest first, an effect whose removal does not hurt the held-out fit beyond the noise (its
marginal gain fails the rule, the accepted effects sharing the level). Each kept effect's
marginal contribution in the joint model is reported.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

from twin_cosim.gap.data.context import DEFAULT_CONTEXT, DiagnosisContext, training_residuals
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.evidence import (
    EFFECTIVE_SAMPLE_SPACING_S,
    CalibrationBasis,
    CalibrationFloor,
)
from twin_cosim.gap.floors.noise import MetricComparison
from twin_cosim.gap.location import dominant_order
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.acceptance import (
    Acceptance,
    Candidate,
    Gain,
    HeldOut,
    JointCandidate,
    Judging,
    Marginal,
    Pair,
    judge,
    size_above_tolerance,
)
from twin_cosim.gap.which.replay import (
    FitResult,
    FitTask,
    JointFitTask,
    Replays,
    SimulateTask,
    Uncertainty,
    UncertaintyTask,
    searches,
    shape_index,
)
from twin_cosim.gap.which.replay_pool import ReplayPool
from twin_cosim.plant_model import Hypothesis

CandidateT = TypeVar("CandidateT", bound=Candidate)


@dataclass(frozen=True)
class Accepted:
    """An accepted effect: its group, fitted values (physical units), context, and the index
    of the round that accepted it (its rivals are that round's other passing hypotheses; 0:
    none recorded)."""

    group: list[str]
    values: tuple[float, ...]
    context: dict[str, float]
    round: int = 0

    @property
    def name(self) -> str:
        """The effect's name (the group's first)."""
        return self.group[0]


@dataclass(frozen=True)
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
    joint : list of JointCandidate
        Hypotheses refitted together with the accepted effects when none passed on top of them,
        best training BIC first.
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
    joint: list[JointCandidate] = field(default_factory=list)
    pairs: list[Pair] = field(default_factory=list)
    pair: Pair | None = None

    @property
    def effect(self) -> str | list[str]:
        """What the round accepted as reports name it: a pair's ``first+second``, a group of
        look-alikes, or one effect's name."""
        if self.pair is not None:
            return self.pair.name
        return list(self.accepted) if len(self.accepted) > 1 else self.accepted[0]

    @property
    def best(self) -> Candidate | None:
        """The accepted candidate (or pair): refitted with the accepted effects when one of the
        joint screen passed (it runs only when no candidate passed on top of them)."""
        if self.pair is not None:
            return self.pair
        judged = [c for c in self.joint if c.passes] or self.candidates
        return next((c for c in judged if self.accepted and c.name == self.accepted[0]), None)


@dataclass(frozen=True)
class Swap:
    """An accepted effect replaced by a rival from its round (:meth:`Selector.swap`).

    ``removed``: the accepted effect taken out; ``candidate``: the rival fitted on top of the
    other accepted effects, judged against the model as it was; ``kept``: whether the swap was
    made.
    """

    removed: str
    candidate: Candidate
    kept: bool = False


@dataclass(frozen=True)
class Refit:
    """An accepted effect replaced by its cold refit (:meth:`Selector.refresh`).

    ``values_before`` and ``values_after``: the effect's fitted values (physical units) before
    and after; ``left_before`` and ``left_after``: the normalised held-out RMS the best
    calibration correction leaves with the model before and after; ``gain``: the refit's gain
    against the rule, the refits tried sharing the level.
    """

    effect: str
    values_before: tuple[float, ...]
    values_after: tuple[float, ...]
    left_before: float
    left_after: float
    gain: Gain

    @property
    def significant(self) -> bool:
        """Whether the refit's gain passes the rule: a model that changed this much may let a
        further round accept an effect."""
        return self.gain.passes


@dataclass(frozen=True)
class Selection:
    """The rounds, the accepted effects (after the backward pass) and their FMU parameters, the
    replays with them, the calibration floor of what they leave with its calibrated replays,
    each kept effect's marginal contribution, the effects the backward pass dropped, the swaps
    tried, the cold refits that replaced their effect, what the training data leave uncertain
    in the final model (its parameters' intervals) and where the time went (wall s, pool tasks
    and replays per phase)."""

    rounds: list[Round]
    effects: list[Accepted]
    plant_parameters: dict[str, float]
    replays: Replays
    floor: CalibrationFloor
    calibrated: Replays
    marginal: list[Marginal] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    swaps: list[Swap] = field(default_factory=list)
    refits: list[Refit] = field(default_factory=list)
    uncertainty: Uncertainty | None = None
    times: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def accepted(self) -> list[list[str]]:
        """The accepted effects' groups, in the order accepted."""
        return [a.group for a in self.effects]


def bic(cost: float, n_parameters: int, train_seconds: float) -> float:
    """Bayesian information criterion of a training fit: ``cost`` the mean squared normalised
    residual, ``train_seconds`` (s) the training duration (one independent sample per
    :data:`~twin_cosim.gap.floors.evidence.EFFECTIVE_SAMPLE_SPACING_S`)."""
    n_eff = max(train_seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0)
    return n_eff * math.log(max(cost, 1e-300)) + n_parameters * math.log(n_eff)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Absolute correlation of two predicted changes (0 when either is constant)."""
    if len(a) != len(b) or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(abs(np.corrcoef(a, b)[0, 1]))


def refitted(accepted: list[Accepted], refit: FitResult) -> list[Accepted]:
    """The accepted effects with the values of their joint refit (``refit.values`` by
    ``effect.parameter``, physical units, in each hypothesis' order)."""
    return [
        dataclasses.replace(
            a,
            values=tuple(v for k, v in refit.values.items() if k.split(".", 1)[0] == a.name),
        )
        for a in accepted
    ]


def rivals(
    rounds: list[Round], accepted: list[Accepted], swapped_out: set[str]
) -> list[tuple[int, Candidate]]:
    """Per accepted effect (its index), the hypotheses that passed its round beside it.

    Parameters
    ----------
    rounds
        The rounds so far (``Accepted.round`` indexes them from 1).
    accepted
        The accepted effects.
    swapped_out
        Effects taken out by earlier swaps (never rivals again).
    """
    taken = {name for a in accepted for name in a.group}
    found = []
    for j, effect in enumerate(accepted):
        if not 1 <= effect.round <= len(rounds):
            continue
        for c in rounds[effect.round - 1].candidates:
            if c.passes and c.name not in taken and c.name not in swapped_out:
                found.append((j, c))
    return found


@dataclass
class Selector:
    """Runs the steps of the selection on a replay pool (module docstring).

    Parameters
    ----------
    pool : ReplayPool
        Replays and fits on the workers, calibration directions.
    library : dict
        The model's hypotheses by name.
    judging : Judging
        The held-out runs.
    settings : DiagnosisSettings
    train_seconds : float
        Length of the training data, s.
    context : DiagnosisContext or None
        The runs (the rounds read the orders of periodic hypotheses off their training
        residual); None for the steps after the rounds alone.
    hypothesis_context : dict or None
        Data-derived settings of the hypotheses besides the orders (encoder resolution, nominal
        dead time).
    """

    pool: ReplayPool
    library: dict[str, Hypothesis]
    judging: Judging
    settings: DiagnosisSettings
    train_seconds: float
    context: DiagnosisContext | None = None
    hypothesis_context: dict[str, float] = field(default_factory=dict)

    def expected_tasks(self) -> int:
        """Pool tasks of a selection that accepts the most effects (for progress bars)."""
        per_round = 2 * len(self.pool.calibrated) + 2
        first = len(self.settings.hypotheses or self.library)
        periodic = sum(1 for h in self.library.values() if h.periodic_in)
        later = periodic + self.settings.later_round_candidates
        searched = self.settings.searched_candidates  # first round: refitted from a search
        rounds = self.settings.max_effects
        pairs = 2 * math.comb(self.settings.pair_candidates, 2)
        joint = 2 * (self.settings.joint_candidates + 1) * (rounds - 1)  # with the refit alone
        swaps = 2 * rounds  # one rival per accepted effect
        replayed = rounds * per_round  # a passing candidate's directions, two corrected replays
        # after each accepted effect and a swap: each effect, a level-and-shape one twice
        shaped = sum(1 for h in self.library.values() if shape_index(h) is not None)
        refreshes = 2 * (rounds + min(shaped, rounds)) * (rounds + 1)
        profiles = shaped * (rounds - 1)  # a later round's level-and-shape fits from a profile
        return (
            1  # the final model's uncertainty
            + per_round * (rounds + 1)
            + 2 * first
            + searched
            + 2 * later * (rounds - 1)
            + profiles
            + pairs
            + joint
            + refreshes
            + swaps
            + replayed
        )

    def run(self, start: Replays) -> Selection:
        """Forward rounds from the replays of the nominal twin, cold refits of the accepted
        effects and swaps for rivals of their round (the rounds resume after a refit whose gain
        passes the rule or a swap, while more effects are allowed), then the backward pass."""
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
        self.pool.keep(base, start)
        while True:
            count = len(accepted)
            base, replays, starts = self.forward(accepted, rounds, base, replays, remaining, starts)
            fresh = fresh and len(accepted) == count
            if not fresh:
                fresh = True
                base, replays, moved = self._refreshed(accepted, base, replays, refits)
                if moved and len(accepted) < settings.max_effects:
                    remaining = self._not_accepted(accepted)
                    continue
            swapped = self.swap(rounds, accepted, base, replays, swaps)
            if swapped is None:
                break
            base, replays = swapped
            fresh = False
            if len(accepted) >= settings.max_effects:
                base, replays, _ = self._refreshed(accepted, base, replays, refits)
                break
            remaining = self._not_accepted(accepted)
        accepted, base, replays, marginal, dropped = self.backward(accepted, base, replays, start)
        threshold = self.judging.threshold(settings)
        floor, calibrated = self.pool.calibration(base, replays, threshold)
        uncertainty = self.pool.uncertainty(self.uncertainty_task(accepted, base), self.library)
        return Selection(
            rounds,
            accepted,
            base,
            replays,
            floor,
            calibrated,
            marginal=marginal,
            dropped=dropped,
            swaps=swaps,
            refits=refits,
            uncertainty=uncertainty,
            times=self.pool.times.as_dict(),
        )

    def uncertainty_task(self, accepted: list[Accepted], base: dict[str, float]) -> UncertaintyTask:
        """What the training data leave uncertain in the model of ``accepted`` (FMU parameters
        ``base``), the calibrated parameters under their prior."""
        return UncertaintyTask(
            base,
            tuple(a.name for a in accepted),
            tuple(a.values for a in accepted),
            tuple(a.context for a in accepted),
            tuple(self.pool.calibrated),
            self.settings.calibration_tolerance,
        )

    def _acceptance(self, tests: int) -> Acceptance:
        """The rule of ``tests`` changes judged together."""
        return self.judging.acceptance(self.settings, tests, len(self.library))

    def _size_above(self, name: str, values: tuple[float, ...], base: dict[str, float]) -> bool:
        """Whether hypothesis ``name`` fitted at ``values`` on top of ``base`` changes a
        calibrated parameter by more than the tolerance (True for other effects)."""
        parameters = {**self.pool.nominal, **base}
        tolerance = self.settings.calibration_tolerance
        return size_above_tolerance(self.library[name], values, parameters, tolerance)

    def _refreshed(
        self,
        accepted: list[Accepted],
        base: dict[str, float],
        replays: Replays,
        refits: list[Refit],
    ) -> tuple[dict[str, float], Replays, bool]:
        """The model after the cold refits (FMU parameters, replays), the refit that replaced
        its effect appended to ``refits``, and whether its gain passed the rule (a further
        round may find more)."""
        refitted = self.refresh(accepted, base, replays)
        if refitted is None:
            return base, replays, False
        base, replays, record = refitted
        refits.append(record)
        return base, replays, record.significant

    def forward(
        self,
        accepted: list[Accepted],
        rounds: list[Round],
        base: dict[str, float],
        replays: Replays,
        remaining: list[str],
        starts: dict[str, tuple[float, ...]],
    ) -> tuple[dict[str, float], Replays, dict[str, tuple[float, ...]]]:
        """Rounds until the gap is not significant, no hypothesis (or pair) passes or the most
        effects are accepted; ``accepted`` and ``rounds`` grow in place. Returns the accepted
        effects' FMU parameters, their replays and the last round's fits (the starts of a later
        round)."""
        settings = self.settings
        while remaining and len(accepted) < settings.max_effects:
            held = self.judging.held_out(replays, self.pool.basis(base))
            floor, calibrated = self.pool.calibration(
                base, replays, self.judging.threshold(settings)
            )
            metrics = self.judging.metrics(calibrated, settings)
            assert self.context is not None, "the rounds read their orders off the runs"
            context = self._orders(training_residuals(self.context, replays.training))
            opened = Round(
                len(rounds) + 1,
                context,
                self.judging.significant(floor.left, metrics, settings),
                float(np.linalg.norm(held.vector)),
                held.residuals.position_rms_um(),
                held.residuals.current_rms(),
                floor,
                metrics,
            )
            if not opened.significant:
                rounds.append(opened)
                break
            candidates = self.replay_corrections(
                self._fit_and_judge(remaining, base, context, held, starts), base, held
            )
            starts = {c.name: tuple(c.fit.values.values()) for c in candidates if self._found(c)}
            joint: list[JointCandidate] = []
            if accepted and not any(c.passes for c in candidates):
                joint = self.screen_joint(candidates, accepted, context, base, held)
            passing = [c for c in candidates if c.passes] or [c for c in joint if c.passes]
            if passing:
                best: Candidate = passing[0]
                group = [best.name] + [
                    c.name
                    for c in passing[1:]
                    if abs(c.judgement.reduction - best.judgement.reduction)
                    < settings.group_reduction_margin
                    and correlation(c.judgement.change, best.judgement.change)
                    >= settings.group_correlation
                ]
                done = dataclasses.replace(
                    opened, candidates=candidates, joint=joint, accepted=group
                )
                found = [(list(group), tuple(best.fit.values.values()))]
                if isinstance(best, JointCandidate):
                    accepted[:] = refitted(accepted, best.refit)
            elif len(accepted) + 2 <= settings.max_effects:
                screened = dataclasses.replace(opened, candidates=candidates, joint=joint)
                pairs = self.replay_corrections(self.screen_pairs(screened, base, held), base, held)
                pair = next((p for p in pairs if p.passes), None)
                if pair is None:
                    rounds.append(dataclasses.replace(screened, pairs=pairs))
                    break
                best = pair
                done = dataclasses.replace(
                    screened, accepted=list(pair.members), pairs=pairs, pair=pair
                )
                found = [([n], v) for n, v in zip(pair.members, pair.member_values, strict=True)]
            else:
                rounds.append(dataclasses.replace(opened, candidates=candidates, joint=joint))
                break
            rounds.append(done)
            for group, values in found:
                for k, earlier in enumerate(accepted):
                    if group[0] in earlier.group[1:]:  # the data now tell it from a look-alike
                        kept = [name for name in earlier.group if name != group[0]]
                        accepted[k] = dataclasses.replace(earlier, group=kept)
                accepted.append(Accepted(group, values, context, done.index))
            base, replays = self.joint(accepted, dict(best.fit.overrides))
            remaining = self._next_candidates(done, {g[0] for g, _ in found}, remaining)
        return base, replays, starts

    def _orders(self, training_residual: Residuals) -> dict[str, float]:
        """The hypotheses' context with the orders of the periodic ones read off the training
        residual left."""
        assert self.context is not None
        context = dict(self.hypothesis_context)
        angle = training_residual.motor_angle
        for key, signal_angle in (
            ("motor_order", angle),
            ("screw_order", self.context.screw_angle(angle)),
        ):
            order = dominant_order(training_residual, training_residual.current, signal_angle)
            context[key] = order if order is not None else DEFAULT_CONTEXT[key]
        return context

    def _fit_and_judge(
        self,
        names: list[str],
        base: dict[str, float],
        context: dict[str, float],
        held: HeldOut,
        starts: dict[str, tuple[float, ...]],
    ) -> list[Candidate]:
        """Fit every hypothesis (from its fit of the round before, in ``starts``, when there
        is one), replay it on the held-out runs and judge it; best training BIC first.

        The first round screens (:meth:`_screened`): every hypothesis but a level and a shape
        is fitted locally from its start values, a level and a shape from its profile over the
        shape (:func:`~twin_cosim.gap.which.replay.profile_start`: its cost is rough in the
        shape, and no local fit screens it); the leading ones by training BIC
        (``searched_candidates`` of those whose fit has a global search,
        :func:`~twin_cosim.gap.which.replay.searches`) are fitted again from their global
        search, which replaces a local fit and competes with a profile fit. The others keep
        their screen fit: a hypothesis the data do not call for leaves its local fit far behind
        the leaders', and its search (most of a cold fit's replays) would not change its place.
        A later round (:meth:`_continued`) starts each fit from the round before's, where a
        search of one generation costs about what a screen would, and fits a level and a shape
        from its profile too.
        """
        if starts:
            fits = self._continued(names, base, context, starts)
        else:
            fits = self._screened(names, base, context)
        acceptance = self._acceptance(len(names))
        replays = self.pool.tasks("candidate_replays", [SimulateTask(f.overrides) for f in fits])
        candidates = []
        for fit, replay in zip(fits, replays, strict=True):
            n_parameters = len(self.library[fit.hypothesis].parameters)
            size_above = self._size_above(fit.hypothesis, tuple(fit.values.values()), base)
            judgement = judge(
                replay, held, self.judging, acceptance, self.settings.worsen_limit, size_above
            )
            train_bic = bic(fit.train_cost, n_parameters, self.train_seconds)
            candidates.append(Candidate(fit, n_parameters, train_bic, replay, judgement))
        return sorted(candidates, key=lambda c: c.bic)

    def replay_corrections(
        self, candidates: list[CandidateT], base: dict[str, float], held: HeldOut
    ) -> list[CandidateT]:
        """The candidates; each that passes every other test gets its gain with the calibration
        corrections replayed, which it must pass too (test 5 of
        :mod:`~twin_cosim.gap.which.acceptance`).

        The model as it is (``base``, its held-out residual ``held``) and the model with the
        candidate are each replayed with the linear calibration correction of its own held-out
        residual along its own calibration directions (those of the model with the candidate
        are replayed for it: a candidate that moves the twin far, an inertia change of 20 %,
        would be corrected less well along the model's), and the gain is judged on these
        replays."""
        tested = [i for i, c in enumerate(candidates) if c.passes]
        if not tested or not self.pool.calibrated:
            return candidates
        models = [(base, held)] + [
            (
                candidates[i].fit.overrides,
                self.judging.held_out(
                    candidates[i].replays, self.pool.basis(candidates[i].fit.overrides)
                ),
            )
            for i in tested
        ]
        tasks = []
        for overrides, model in models:
            coefficients = model.basis.correction(model.vector)[0].tolist()
            correction = dict(zip(model.basis.names, coefficients, strict=True))
            tasks.append(SimulateTask(self.pool.corrected(overrides, correction)))
        replays = self.pool.tasks("replayed_corrections", tasks)
        before, *afters = (self.judging.vector(self.judging.residuals(r)) for r in replays)
        found = list(candidates)
        for i, after in zip(tested, afters, strict=True):
            judgement = candidates[i].judgement
            replayed = judgement.gain.of(before, after, self.judging.duration_s)
            found[i] = dataclasses.replace(
                candidates[i], judgement=dataclasses.replace(judgement, replayed=replayed)
            )
        return found

    def _found(self, candidate: Candidate) -> bool:
        """Whether a candidate's fit is a start for the next round: one from a search (its
        global search or its profile) or of a hypothesis without one. A local fit the first
        round's screen left alone found no valley; the next round searches that hypothesis
        afresh."""
        fit = candidate.fit
        return fit.search_replays > 0 or not searches(self.library[fit.hypothesis])

    def _screened(
        self, names: list[str], base: dict[str, float], context: dict[str, float]
    ) -> list[FitResult]:
        """The first round's fits: every hypothesis fitted locally from its start values, a
        level and a shape from its profile; the leading ``searched_candidates`` by training
        BIC among those whose fit has a global search fitted again from it (in the order of
        ``names``; a leader keeps its search, or the better of its profile fit and its search,
        with the replays of both: :func:`_better_of`)."""
        phase = "first_round_fits"
        shaped = {n for n in names if shape_index(self.library[n]) is not None}
        local = self.pool.tasks(
            phase,
            [
                FitTask(n, base, context, profile=True)
                if n in shaped
                else FitTask(n, base, context, search=False)
                for n in names
            ],
        )
        searchable = [f for f in local if searches(self.library[f.hypothesis])]
        leaders = sorted(
            searchable,
            key=lambda f: bic(
                f.train_cost, len(self.library[f.hypothesis].parameters), self.train_seconds
            ),
        )[: self.settings.searched_candidates]
        searched = self.pool.tasks(phase, [FitTask(f.hypothesis, base, context) for f in leaders])
        return _better_of(local, searched)

    def _continued(
        self,
        names: list[str],
        base: dict[str, float],
        context: dict[str, float],
        starts: dict[str, tuple[float, ...]],
    ) -> list[FitResult]:
        """A later round's fits: each hypothesis from its fit of the round before (a search of
        one generation around it), a level and a shape also from its profile (the accepted
        effects can move its valley out of that generation's reach), the better kept."""
        shaped = [n for n in names if shape_index(self.library[n]) is not None]
        fits = self.pool.tasks(
            "later_round_fits",
            [FitTask(n, base, context, starts.get(n)) for n in names]
            + [FitTask(n, base, context, profile=True) for n in shaped],
        )
        return _better_of(fits[: len(names)], fits[len(names) :])

    def _next_candidates(self, done: Round, fitted: set[str], remaining: list[str]) -> list[str]:
        """Periodic hypotheses and the best of the round by held-out reduction; a look-alike of
        the accepted effects stays a candidate (two effects at once can look alike alone)."""
        left = [n for n in remaining if n not in fitted]
        periodic = [n for n in left if self.library[n].periodic_in]
        ranked = sorted(
            (c for c in done.candidates if c.name in left and c.name not in periodic),
            key=lambda c: -c.judgement.reduction,
        )
        return periodic + [c.name for c in ranked[: self.settings.later_round_candidates]]

    def _not_accepted(self, accepted: list[Accepted]) -> list[str]:
        """The hypotheses a resumed round fits: all but the accepted effects."""
        names = {a.name for a in accepted}
        return [n for n in (self.settings.hypotheses or self.library) if n not in names]

    def refit_task(self, accepted: list[Accepted]) -> JointFitTask:
        """The refit of effects together on the training data, with the calibrated parameters
        under their prior."""
        return JointFitTask(
            tuple(a.name for a in accepted),
            tuple(a.values for a in accepted),
            tuple(a.context for a in accepted),
            tuple(self.pool.calibrated),
            self.settings.calibration_tolerance,
        )

    def joint(
        self, accepted: list[Accepted], sequential: dict[str, float]
    ) -> tuple[dict[str, float], Replays]:
        """The accepted effects' parameters: refitted together when that judges better on the
        held-out data than the sequential fit, and their replays (the sequential replay runs
        beside the refit)."""
        (refit,), (replays,) = self.pool.joint_fits(
            "joint_refits",
            [self.refit_task(accepted)],
            self.library,
            [SimulateTask(sequential, with_training=True)],
        )
        joint = refit.overrides
        joint_replays = self.pool.tasks("joint_refits", [SimulateTask(joint, with_training=True)])
        left_joint = np.linalg.norm(self.pool.left(joint, joint_replays[0]))
        if left_joint < np.linalg.norm(self.pool.left(sequential, replays)):
            accepted[:] = refitted(accepted, refit)
            return joint, joint_replays[0]
        return sequential, replays

    def screen_joint(
        self,
        candidates: list[Candidate],
        accepted: list[Accepted],
        context: dict[str, float],
        base: dict[str, float],
        held: HeldOut,
    ) -> list[JointCandidate]:
        """The round's leading hypotheses by training BIC refitted together with the accepted
        effects (and the calibrated parameters under their prior), each judged as one candidate
        without a further calibration correction, against the better on the held-out data of
        the model as it is and the same refit without a candidate; best training BIC first
        (module docstring).

        Parameters
        ----------
        candidates
            The round's candidates, fitted on top of the accepted effects and judged (best
            training BIC first); none passed.
        accepted
            The accepted effects.
        context
            The round's hypothesis context.
        base
            FMU parameters of the accepted effects.
        held
            The held-out residual at the start of the round.
        """
        fitted = [c for c in candidates if math.isfinite(c.bic) and c.fit.values]
        leaders = fitted[: self.settings.joint_candidates]
        if not leaders:
            return []
        refits, _ = self.pool.joint_fits(
            "joint_screen_fits",
            [self.refit_task(accepted)]
            + [
                self.refit_task(
                    [*accepted, Accepted([c.name], tuple(c.fit.values.values()), context)]
                )
                for c in leaders
            ],
            self.library,
        )
        replays = self.pool.tasks(
            "joint_screen_replays", [SimulateTask(r.overrides) for r in refits]
        )
        # The refits moved the calibrated parameters within their prior themselves: judged
        # without a further calibration correction (that would count calibration error twice),
        # against what the same refit reaches without a candidate when that leaves less than the
        # model as it is (the gain is then the candidate's alone).
        plain = CalibrationBasis([], np.zeros((len(held.vector), 0)))
        held = HeldOut(held.residuals, held.vector, plain)
        without = self.judging.held_out(replays[0], plain)
        if np.linalg.norm(without.vector) < np.linalg.norm(held.vector):
            held = without
        acceptance = self._acceptance(len(candidates) + len(leaders))
        joint = []
        for c, refit, replay in zip(leaders, refits[1:], replays[1:], strict=True):
            prefix = f"{c.name}."
            values = {k[len(prefix) :]: v for k, v in refit.values.items() if k.startswith(prefix)}
            fit = FitResult(
                c.name,
                values,
                refit.overrides,
                refit.train_cost,
                refit.replays,
                refit.message,
                iterations=refit.iterations,
            )
            size_above = self._size_above(c.name, tuple(values.values()), base)
            judgement = judge(
                replay, held, self.judging, acceptance, self.settings.worsen_limit, size_above
            )
            train_bic = bic(refit.train_cost, c.n_parameters, self.train_seconds)
            joint.append(
                JointCandidate(fit, c.n_parameters, train_bic, replay, judgement, refit=refit)
            )
        return sorted(joint, key=lambda c: c.bic)

    def screen_pairs(self, opened: Round, base: dict[str, float], held: HeldOut) -> list[Pair]:
        """Pairs of the round's leading hypotheses by training BIC, the second fitted on top of
        the first, judged as one candidate and each member against the other alone (module
        docstring); best training BIC first.

        Parameters
        ----------
        opened
            The round: its hypothesis context and its candidates, fitted and judged (best
            training BIC first).
        base
            FMU parameters of the accepted effects.
        held
            The held-out residual at the start of the round.
        """
        candidates, context = opened.candidates, opened.context
        leaders = [c for c in candidates if math.isfinite(c.bic) and c.fit.values]
        couples = list(itertools.combinations(leaders[: self.settings.pair_candidates], 2))
        if not couples:
            return []
        fits = self.pool.tasks(
            "pair_fits",
            [
                FitTask(b.name, dict(a.fit.overrides), context, tuple(b.fit.values.values()))
                for a, b in couples
            ],
        )
        replays = self.pool.tasks("pair_replays", [SimulateTask(f.overrides) for f in fits])
        acceptance = self._acceptance(len(candidates) + len(opened.joint) + len(couples))
        judging = self.judging
        pairs = []
        for (a, b), fit, replay in zip(couples, fits, replays, strict=True):
            values = (tuple(a.fit.values.values()), tuple(fit.values.values()))
            n_parameters = a.n_parameters + b.n_parameters
            size_above = self._size_above(a.name, values[0], base) and self._size_above(
                b.name, values[1], a.fit.overrides
            )
            judgement = judge(
                replay, held, judging, acceptance, self.settings.worsen_limit, size_above, shares=2
            )
            with_both = held.basis.correction(judging.vector(judging.residuals(replay)))[1]
            within, earn = [], True
            for member, other in ((a, b), (b, a)):
                alone = judging.vector(judging.residuals(other.replays))
                without = held.basis.correction(alone)[1]
                gain = acceptance.gain(without, with_both)
                within.append(
                    Marginal(
                        member.name,
                        gain.evidence_z,
                        gain.excess_share,
                        float(np.linalg.norm(without)),
                        float(np.linalg.norm(with_both)),
                    )
                )
                earn = earn and gain.passes
            fitted = FitResult(
                f"{a.name}+{b.name}",
                {f"{a.name}.{k}": v for k, v in a.fit.values.items()}
                | {f"{b.name}.{k}": v for k, v in fit.values.items()},
                fit.overrides,
                fit.train_cost,
                fit.replays,
                fit.message,
            )
            pairs.append(
                Pair(
                    fitted,
                    n_parameters,
                    bic(fit.train_cost, n_parameters, self.train_seconds),
                    replay,
                    judgement,
                    members=(a.name, b.name),
                    member_values=values,
                    within=tuple(within),
                    members_earn_place=earn,
                )
            )
        return sorted(pairs, key=lambda p: p.bic)

    def refresh(
        self, accepted: list[Accepted], base: dict[str, float], replays: Replays
    ) -> tuple[dict[str, float], Replays, Refit] | None:
        """The model with its best cold refit of one accepted effect and the refit's record, or
        None when no refit leaves less than the model as it is (module docstring).

        Parameters
        ----------
        accepted
            The accepted effects; the refitted one's values are replaced in place.
        base, replays
            FMU parameters of the accepted effects and their replays (training and held-out).

        Returns
        -------
        tuple or None
            FMU parameters and replays of the model with the refit, and its record (None: a
            single effect, or no refit leaves less).
        """
        if len(accepted) < 2:
            return None
        library = self.library
        movable = [a for a in accepted if library[a.name].kind == "continuous"]
        tries = [(a, False) for a in movable] + [
            (a, True) for a in movable if shape_index(library[a.name]) is not None
        ]
        fits = self.pool.tasks(
            "refresh_fits",
            [
                FitTask(
                    a.name,
                    {k: v for k, v in base.items() if k not in library[a.name].sets},
                    a.context,
                    profile=profile,
                )
                for a, profile in tries
            ],
        )
        trials = self.pool.tasks(
            "refresh_fits", [SimulateTask(f.overrides, with_training=True) for f in fits]
        )
        before = self.pool.left(base, replays)
        left_before = float(np.linalg.norm(before))
        best, choice = left_before, None
        for (effect, _), fit, trial in zip(tries, fits, trials, strict=True):
            after = self.pool.left(fit.overrides, trial)
            left = float(np.linalg.norm(after))
            if left < best:
                best, choice = left, (effect, fit, trial, after)
        if choice is None:
            return None
        effect, fit, trial, after = choice
        record = Refit(
            effect.name,
            effect.values,
            tuple(fit.values.values()),
            left_before,
            best,
            self._acceptance(len(tries)).gain(before, after),
        )
        j = next(k for k, a in enumerate(accepted) if a is effect)
        accepted[j] = dataclasses.replace(effect, values=record.values_after)
        return dict(fit.overrides), trial, record

    def swap(
        self,
        rounds: list[Round],
        accepted: list[Accepted],
        base: dict[str, float],
        replays: Replays,
        records: list[Swap],
    ) -> tuple[dict[str, float], Replays] | None:
        """The model with its best passing swap made, or None when no swap passes (module
        docstring).

        Parameters
        ----------
        rounds
            The rounds so far.
        accepted
            The accepted effects; the swapped one is replaced in place.
        base, replays
            FMU parameters of the accepted effects and their replays (training and held-out).
        records
            The swaps tried so far; this call's are appended.

        Returns
        -------
        tuple or None
            FMU parameters and replays of the model after the swap (its joint refit when that
            judged better).
        """
        trials = rivals(rounds, accepted, {r.removed for r in records if r.kept})
        if not trials:
            return None
        library = self.library
        others = [
            {k: v for k, v in base.items() if k not in library[accepted[j].name].sets}
            for j, _ in trials
        ]
        fits = self.pool.tasks(
            "swap_fits",
            [
                FitTask(c.name, o, accepted[j].context, tuple(c.fit.values.values()))
                for (j, c), o in zip(trials, others, strict=True)
            ],
        )
        models = [
            accepted[:j]
            + [
                dataclasses.replace(
                    accepted[j], group=[fit.hypothesis], values=tuple(fit.values.values())
                )
            ]
            + accepted[j + 1 :]
            for (j, _), fit in zip(trials, fits, strict=True)
        ]
        count = len(trials)
        refits, sequential = self.pool.joint_fits(
            "swap_fits",
            [self.refit_task(m) for m in models],
            self.library,
            [SimulateTask(f.overrides, with_training=True) for f in fits],
        )
        joint = self.pool.tasks(
            "swap_fits", [SimulateTask(r.overrides, with_training=True) for r in refits]
        )
        judging = self.judging
        held = judging.held_out(replays, self.pool.basis(base))

        def left(trial: Replays) -> float:
            vector = judging.vector(judging.residuals(trial))
            return float(np.linalg.norm(held.basis.correction(vector)[1]))

        acceptance = self._acceptance(count)
        tried = []
        for k, ((j, rival), fit, model) in enumerate(zip(trials, fits, models, strict=True)):
            overrides, trial = dict(fit.overrides), sequential[k]
            if left(joint[k]) < left(trial):
                overrides, trial = dict(refits[k].overrides), joint[k]
            n_parameters = sum(len(library[a.name].parameters) for a in model)
            size_above = self._size_above(rival.name, tuple(fit.values.values()), others[k])
            candidate = Candidate(
                FitResult(fit.hypothesis, fit.values, overrides, fit.train_cost, fit.replays, ""),
                len(library[rival.name].parameters),
                bic(fit.train_cost, n_parameters, self.train_seconds),
                trial,
                judge(trial, held, judging, acceptance, self.settings.worsen_limit, size_above),
            )
            tried.append((model, accepted[j].name, candidate))
        passing = [(model, candidate) for model, _, candidate in tried if candidate.passes]
        made = min(passing, key=lambda pair: pair[1].bic) if passing else None
        records.extend(
            Swap(removed, candidate, kept=made is not None and candidate is made[1])
            for _, removed, candidate in tried
        )
        if made is None:
            return None
        model, candidate = made
        accepted[:] = model
        return dict(candidate.fit.overrides), candidate.replays

    def without_each(
        self, accepted: list[Accepted], start: Replays
    ) -> list[tuple[FitResult | None, Replays]]:
        """Per accepted effect, the model refitted without it (the refit, replays); the refits
        run at once. Without a single effect it is the nominal twin (``start``, no refit): the
        best calibration correction of its held-out residual gives calibration error every
        benefit of the doubt already."""
        if len(accepted) == 1:
            return [(None, start)]
        refits, _ = self.pool.joint_fits(
            "backward_pass",
            [self.refit_task(accepted[:j] + accepted[j + 1 :]) for j in range(len(accepted))],
            self.library,
        )
        withouts = self.pool.tasks(
            "backward_pass", [SimulateTask(r.overrides, with_training=True) for r in refits]
        )
        return [(r, w) for r, w in zip(refits, withouts, strict=True)]

    def backward(
        self,
        accepted: list[Accepted],
        base: dict[str, float],
        replays: Replays,
        start: Replays,
    ) -> tuple[list[Accepted], dict[str, float], Replays, list[Marginal], list[str]]:
        """Drop, weakest first, accepted effects whose removal does not hurt the held-out fit
        beyond the noise; the kept effects' marginal contributions. A single effect is kept: it
        passed the stricter test of its round.

        Parameters
        ----------
        accepted
            The accepted effects, in the order accepted.
        base, replays
            FMU parameters of the accepted effects and their replays (training and held-out).
        start
            Replays of the nominal twin (the model without a single effect).

        Returns
        -------
        tuple
            The kept effects, their FMU parameters and replays, their marginal contributions
            and the names of the effects dropped.
        """
        dropped: list[str] = []
        while accepted:
            with_all = self.pool.left(base, replays)
            acceptance = self._acceptance(len(accepted))
            trials = []
            for j, (refit, without) in enumerate(self.without_each(accepted, start)):
                left = self.pool.left(refit.overrides if refit else {}, without)
                gain = acceptance.gain(left, with_all)
                marginal = Marginal(
                    accepted[j].name,
                    gain.evidence_z,
                    gain.excess_share,
                    float(np.linalg.norm(left)),
                    float(np.linalg.norm(with_all)),
                )
                trials.append((gain, j, refit, without, marginal))
            weakest = min(trials, key=lambda trial: trial[0].strength)
            if len(accepted) == 1 or weakest[0].passes:
                return accepted, base, replays, [trial[4] for trial in trials], dropped
            _, j, refit, replays, _ = weakest
            dropped.append(accepted[j].name)
            assert refit is not None, "a single effect is kept"
            accepted, base = refitted(accepted[:j] + accepted[j + 1 :], refit), refit.overrides
        return accepted, base, replays, [], dropped


def _better_of(fits: list[FitResult], others: list[FitResult]) -> list[FitResult]:
    """``fits``, each replaced by the fit of the same hypothesis in ``others`` (a search)
    when its own comes from no search (a local fit), or when its own comes from a search too
    and the other fits the training data at least as well; each keeps the replays of both."""
    by_name = {f.hypothesis: f for f in others}
    found = []
    for fit in fits:
        other = by_name.get(fit.hypothesis)
        if other is not None:
            searched = fit.search_replays > 0
            best = other if not searched or other.train_cost <= fit.train_cost else fit
            fit = dataclasses.replace(
                best,
                replays=fit.replays + other.replays,
                search_replays=fit.search_replays + other.search_replays,
            )
        found.append(fit)
    return found
