"""The records of the selection: fitted hypotheses judged on the held-out data (a single one,
or a pair fitted together), what a kept effect adds to the joint model, a round, a cold refit,
the selection's outcome, and the ranking helpers (BIC, correlation of predicted changes)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from twin_cosim.gap.floors.calibration import CalibrationFloor
from twin_cosim.gap.floors.evidence import EFFECTIVE_SAMPLE_SPACING_S
from twin_cosim.gap.floors.noise import MetricComparison
from twin_cosim.gap.which.replay import FitResult, Replays


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


@dataclass
class Swap:
    """An accepted effect replaced by a rival from its round (:mod:`twin_cosim.gap.which.swaps`).

    ``removed``: the accepted effect taken out; ``candidate``: the rival fitted on top of the
    other accepted effects, judged against the model as it was (its evidence, share of the
    excess energy and the other acceptance tests); ``kept``: whether the swap was made.
    """

    removed: str
    candidate: Candidate
    kept: bool = False


@dataclass(frozen=True)
class Refit:
    """An accepted effect replaced by its cold refit (:mod:`twin_cosim.gap.which.refresh`).

    ``values_before`` and ``values_after``: the effect's fitted values (physical units) before
    and after; ``left_before`` and ``left_after``: the normalised held-out RMS the best
    calibration correction leaves with the model before and after; ``evidence_z`` and
    ``excess_share``: the refit's gain judged as a round's candidate is
    (:func:`~twin_cosim.gap.evidence.improvement_z`, :func:`~twin_cosim.gap.evidence.excess_share`)
    against ``critical_z`` (the refits tried share the level) and ``fair_share``.
    """

    effect: str
    values_before: tuple[float, ...]
    values_after: tuple[float, ...]
    left_before: float
    left_after: float
    evidence_z: float
    critical_z: float
    excess_share: float
    fair_share: float

    @property
    def significant(self) -> bool:
        """Whether the refit's gain passes the evidence and fair-share tests of a candidate: a
        model that changed this much may let a further round accept an effect."""
        return self.evidence_z >= self.critical_z and self.excess_share >= self.fair_share


@dataclass(frozen=True)
class Selection:
    """The rounds, the accepted effects (after the backward pass) and their FMU parameters, the
    replays with them, the calibration floor of what they leave with its calibrated replays,
    each kept effect's marginal contribution, the effects the backward pass dropped, the swaps
    tried, the cold refits that replaced their effect and where the time went (wall s, pool
    tasks and replays per phase)."""

    rounds: list[Round]
    accepted: list[list[str]]
    plant_parameters: dict[str, float]
    replays: Replays
    floor: CalibrationFloor
    calibrated: Replays
    marginal: list[Marginal] = field(default_factory=list)
    dropped: list[str] = field(default_factory=list)
    swaps: list[Swap] = field(default_factory=list)
    refits: list[Refit] = field(default_factory=list)
    times: dict[str, dict[str, float]] = field(default_factory=dict)


@dataclass
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


def bic(cost: float, n_parameters: int, train_seconds: float) -> float:
    """Bayesian information criterion of a training fit: ``cost`` the mean squared normalised
    residual, ``train_seconds`` (s) the training duration (one independent sample per
    :data:`~twin_cosim.gap.evidence.EFFECTIVE_SAMPLE_SPACING_S`)."""
    n_eff = max(train_seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0)
    return n_eff * math.log(max(cost, 1e-300)) + n_parameters * math.log(n_eff)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Absolute correlation of two predicted changes (0 when either is constant)."""
    if len(a) != len(b) or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(abs(np.corrcoef(a, b)[0, 1]))
