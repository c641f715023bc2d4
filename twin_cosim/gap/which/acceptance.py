"""Whether a change passes: the acceptance rule, the held-out runs it judges on, and the judged
candidates of the selection.

**The rule** (:class:`Acceptance`): a change of the model (an effect added, a pair, a swap, a
cold refit, an effect kept in the backward pass) improves the held-out fit beyond the noise
after the best calibration correction with and without it (what calibration error can explain
is not the change's to claim): its evidence z (:func:`twin_cosim.gap.floors.evidence.improvement_z`)
reaches the one-sided quantile of ``acceptance_level`` shared by the changes judged together
(Bonferroni), and it removes at least its fair share (1 / the library's size, per hypothesis
it holds) of the energy above the noise (:class:`Gain`). Every step of the selection asks this
one value.

A fitted hypothesis *passes* (:func:`judge`) when, on the held-out data,

1. the gap is significant: what the best calibration correction leaves fails the test against
   noise at the floors (:func:`twin_cosim.gap.floors.evidence.gap_threshold`, level
   ``significance_level``), or a figure of merit (E_pk, ITAE, IAU) is off beyond what noise
   makes; calibration error alone is no gap (the round's test: :meth:`Judging.significant`);
2. it cuts the normalised RMS (it makes the held-out gap smaller as it stands);
3. its gain passes the rule, and a change of a calibrated parameter itself (Coulomb level,
   backlash, inertia, stiffness) exceeds the tolerance (:func:`size_above_tolerance`);
4. it is consistent: it makes neither the position nor the current held-out RMS worse than
   ``worsen_limit`` (1.1) times what it was, plus the noise floor (a wrong effect can trade one
   signal for the other);
5. its gain holds with the calibration corrections replayed: the model with it and the model
   without it, each replayed with the linear calibration correction of its own held-out
   residual along its own calibration directions, pass the rule (evidence and fair share) of
   test 3 against each other
   (:meth:`Gain.of`). Tests 1-4 judge linear corrections along the directions of the model
   without it, and on a trajectory whose response to the calibrated parameters is far from
   linear (creeps that stick and slip) what calibration error leaves can look like an
   effect's signature. Asked only of candidates that pass tests 1-4 and were judged after a
   calibration correction (a single effect or a pair of a round; not a joint refit, which
   moved the calibrated parameters itself, nor a swap): its calibration directions and one
   replay each, beside one replay of the model without it.

What a judgement measured is an immutable :class:`Judgement`; a :class:`Candidate` is a fit
with its judgement, a :class:`Pair` two hypotheses fitted together and judged as one.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from twin_cosim.gap.data.residuals import Residuals, residuals_of, rms
from twin_cosim.gap.floors.evidence import (
    CalibrationBasis,
    critical_z,
    excess_share,
    fair_share,
    gap_threshold,
    improvement_z,
    normalised_vector,
)
from twin_cosim.gap.floors.noise import Floors, MetricComparison, compare_metrics, metrics_off
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.replay import FitResult, Replays
from twin_cosim.measured import MeasuredRun
from twin_cosim.plant_model import Hypothesis
from twin_cosim.reference import ReferenceGrid


@dataclass(frozen=True)
class Gain:
    """What a change does to the residual the best calibration correction leaves, against what
    the rule asks of it.

    ``evidence_z``: the evidence of the improvement beyond the noise, and ``critical_z`` what
    the rule asks of it; ``excess_share``: the share of the energy above the noise it removes,
    and ``fair_share`` what the rule asks of it.
    """

    evidence_z: float
    critical_z: float
    excess_share: float
    fair_share: float

    @property
    def passes(self) -> bool:
        """Whether the change is beyond the noise and takes at least its fair share."""
        return not self.failed

    @property
    def failed(self) -> list[str]:
        """The tests of the rule it fails: ``evidence`` (z below the critical z), ``fair
        share`` (less of the excess energy than its fair share)."""
        tests = [("evidence", self.evidence_z >= self.critical_z)]
        tests.append(("fair share", self.excess_share >= self.fair_share))
        return [name for name, passed in tests if not passed]

    def of(self, before: np.ndarray, after: np.ndarray, duration_s: float) -> Gain:
        """The gain of another change from ``before`` to ``after`` (normalised residual vectors)
        against the same rule (critical z and fair share), on ``duration_s`` held-out
        seconds."""
        return dataclasses.replace(
            self,
            evidence_z=improvement_z(before, after, duration_s),
            excess_share=excess_share(before, after),
        )

    @property
    def strength(self) -> float:
        """The weaker of the two tests as a ratio to what it asks (>= 1: both pass)."""
        return min(self.evidence_z / self.critical_z, self.excess_share / self.fair_share)


@dataclass(frozen=True)
class Acceptance:
    """The acceptance rule of the changes judged together.

    Attributes
    ----------
    level : float
        Family-wise level (``acceptance_level``).
    tests : int
        Changes judged together (the Bonferroni count).
    hypotheses : int
        Hypotheses of the library (one hypothesis' fair share is 1 / that).
    duration_s : float
        Held-out time the changes are judged on, s.
    """

    level: float
    tests: int
    hypotheses: int
    duration_s: float

    def gain(self, before: np.ndarray, after: np.ndarray, shares: int = 1) -> Gain:
        """The gain of a change from ``before`` to ``after`` (the normalised residual vectors
        the best calibration correction leaves without and with it), ``shares`` hypotheses'
        fair share asked of it."""
        return Gain(
            improvement_z(before, after, self.duration_s),
            critical_z(self.level, self.tests),
            excess_share(before, after),
            shares * fair_share(self.hypotheses),
        )


@dataclass(frozen=True)
class HeldOut:
    """The held-out residual of a model that changes are judged against.

    Attributes
    ----------
    residuals : Residuals
        The held-out residuals.
    vector : numpy.ndarray
        Their normalised vector (its norm: the normalised RMS).
    basis : CalibrationBasis
        Calibration directions around the model's parameters.
    """

    residuals: Residuals
    vector: np.ndarray
    basis: CalibrationBasis

    @cached_property
    def left(self) -> np.ndarray:
        """What the best calibration correction leaves of the vector."""
        return self.basis.correction(self.vector)[1]


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

    def held_out(self, replays: Replays, basis: CalibrationBasis) -> HeldOut:
        """The held-out residual of ``replays``, with the calibration directions around them."""
        residuals = self.residuals(replays)
        return HeldOut(residuals, self.vector(residuals), basis)

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
        return left >= self.threshold(settings) or metrics_off(metrics)

    def threshold(self, settings: DiagnosisSettings) -> float:
        """Normalised RMS at which what is left on these runs is a gap (beyond noise)."""
        return gap_threshold(self.duration_s, settings.significance_level)

    def acceptance(self, settings: DiagnosisSettings, tests: int, hypotheses: int) -> Acceptance:
        """The acceptance rule of ``tests`` changes judged together on these runs, for a
        library of ``hypotheses``."""
        return Acceptance(settings.acceptance_level, tests, hypotheses, self.duration_s)


def size_above_tolerance(
    hypothesis: Hypothesis,
    values: tuple[float, ...],
    parameters: dict[str, float],
    tolerance: float,
) -> bool:
    """Whether a fitted change of a calibrated parameter (``values``, physical units, on top of
    the FMU ``parameters``) exceeds the calibration ``tolerance`` (relative); True for effects
    that change no calibrated parameter."""
    if hypothesis.relative_size is None or not values:
        return True
    return hypothesis.relative_size(np.array(values), parameters) >= tolerance


@dataclass(frozen=True)
class Judgement:
    """What the acceptance tests measured of a fitted candidate on the held-out data.

    ``holdout_rms`` and ``explained`` are normalised RMS values (1 = noise at the floors);
    ``reduction`` and ``reduction_beyond_calibration`` are fractions; ``gain`` is its gain
    against the rule; ``position_rms_um`` is the held-out position gap in um and
    ``current_rms`` the held-out current gap in A (V for EMPS); ``change`` is the change of the
    normalised held-out vector it predicts; ``replayed`` is its gain with the calibration
    corrections replayed (test 5 of the module docstring; None where not asked).
    """

    holdout_rms: float
    reduction: float
    reduction_beyond_calibration: float
    explained: float
    gain: Gain
    size_above_tolerance: bool
    consistent: bool
    position_rms_um: float  # um
    current_rms: float  # A
    change: np.ndarray = field(repr=False)
    replayed: Gain | None = None

    @property
    def passes(self) -> bool:
        """Whether it passes every test (the gap's significance is the round's)."""
        return not self.failed

    @property
    def failed(self) -> list[str]:
        """The tests it fails, in the order of the module docstring: ``reduction`` (it does not
        cut the normalised RMS), ``evidence`` and ``fair share`` (its gain against the rule),
        ``tolerance`` (a calibrated parameter changed by less than the tolerance),
        ``consistency`` (one signal's held-out RMS made worse), ``replayed correction`` (its gain
        does not hold with the calibration corrections replayed)."""
        failed = [] if self.reduction > 0.0 else ["reduction"]
        failed += self.gain.failed
        failed += [] if self.size_above_tolerance else ["tolerance"]
        failed += [] if self.consistent else ["consistency"]
        held = self.replayed is None or self.replayed.passes
        return failed + ([] if held else ["replayed correction"])


def judge(
    replays: Replays,
    held: HeldOut,
    judging: Judging,
    acceptance: Acceptance,
    worsen_limit: float,
    size_above: bool,
    shares: int = 1,
) -> Judgement:
    """The held-out figures and acceptance tests of a fitted candidate.

    Parameters
    ----------
    replays
        The candidate's held-out replays.
    held
        The held-out residual of the model without the candidate.
    judging
        The held-out runs.
    acceptance
        The rule of the candidates judged with it.
    worsen_limit
        Largest factor by which it may make either signal's held-out RMS worse.
    size_above
        Whether its change of a calibrated parameter exceeds the tolerance.
    shares
        Hypotheses the candidate holds: the fair share of the excess energy it must remove is
        that many times one hypothesis'.
    """
    sigma_x, sigma_i = judging.floors.sigma_position_m, judging.floors.sigma_current
    after = judging.residuals(replays)
    after_vector = judging.vector(after)
    before_rms = float(np.linalg.norm(held.vector))
    holdout_rms = float(np.linalg.norm(after_vector))
    left_with = held.basis.correction(after_vector)[1]
    without, with_ = float(np.linalg.norm(held.left)), float(np.linalg.norm(left_with))
    worse_x = rms(after.position) - worsen_limit * rms(held.residuals.position)  # m
    worse_i = rms(after.current) - worsen_limit * rms(held.residuals.current)  # A
    return Judgement(
        holdout_rms=holdout_rms,
        reduction=1.0 - holdout_rms / before_rms if before_rms else 0.0,
        reduction_beyond_calibration=1.0 - with_ / without if without > 0 else 0.0,
        explained=math.sqrt(max(before_rms**2 - holdout_rms**2, 0.0)),
        gain=acceptance.gain(held.left, left_with, shares),
        size_above_tolerance=size_above,
        consistent=worse_x <= sigma_x and worse_i <= sigma_i,
        position_rms_um=after.position_rms_um(),
        current_rms=after.current_rms(),
        change=held.vector - after_vector,
    )


@dataclass(frozen=True)
class Marginal:
    """What one effect adds to a model on the held-out data.

    ``evidence_z``: the evidence that the model with it fits better than the model without it;
    ``excess_share``: the share of the energy above the noise it removes from the model without
    it; ``left_without`` and ``left_with``: the normalised RMS the best calibration correction
    leaves without and with it.
    """

    effect: str
    evidence_z: float
    excess_share: float
    left_without: float
    left_with: float


@dataclass(frozen=True)
class Candidate:
    """A fitted hypothesis judged on the held-out data: its fit, its count of parameters, its
    training BIC, its held-out replays and its judgement."""

    fit: FitResult
    n_parameters: int
    bic: float
    replays: Replays = field(repr=False)
    judgement: Judgement

    @property
    def name(self) -> str:
        """The hypothesis' name."""
        return self.fit.hypothesis

    @property
    def passes(self) -> bool:
        """Whether it passes every acceptance test."""
        return self.judgement.passes


@dataclass(frozen=True)
class JointCandidate(Candidate):
    """A hypothesis refitted together with the accepted effects (and the calibrated parameters
    under their prior), judged as one candidate against the model as it is.

    Attributes
    ----------
    refit : FitResult
        The joint refit: every effect's values by ``effect.parameter`` (physical units), the
        calibrated parameters' by ``calibration.name``, and the FMU parameters of all of them.
    """

    refit: FitResult = field(repr=False)


@dataclass(frozen=True)
class Pair(Candidate):
    """Two hypotheses fitted together (the second on top of the first) and judged as one.

    Attributes
    ----------
    members : tuple of str
        The two hypotheses, the one fitted first (better training BIC alone) first.
    member_values : tuple of tuple of float
        Each member's fitted values (physical units): the first's own fit, the second's on top.
    within : tuple of Marginal
        Per member, what it adds to the other member's fit alone on the held-out data.
    members_earn_place : bool
        Whether each member's addition passes the rule.
    """

    members: tuple[str, ...] = ()
    member_values: tuple[tuple[float, ...], ...] = ()
    within: tuple[Marginal, ...] = ()
    members_earn_place: bool = False

    @property
    def passes(self) -> bool:
        """Whether the pair passes every test and each member earns its place."""
        return self.judgement.passes and self.members_earn_place
