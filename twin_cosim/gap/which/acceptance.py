"""The held-out runs, and judging a fitted hypothesis on them.

A fitted hypothesis *passes* (:func:`judge`) when, on the held-out data,

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

(The significance of the gap, test 1, is the round's: :meth:`Judging.significant`.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from twin_cosim.gap.data.residuals import Residuals, residuals_of, rms
from twin_cosim.gap.floors.calibration import CalibrationBasis, normalised_vector
from twin_cosim.gap.floors.evidence import excess_share, fair_share, gap_threshold, improvement_z
from twin_cosim.gap.floors.noise import Floors, MetricComparison, compare_metrics, metrics_off
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.replay import Replays
from twin_cosim.gap.which.rounds import Candidate
from twin_cosim.measured import MeasuredRun
from twin_cosim.reference import ReferenceGrid


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


def judge(
    candidate: Candidate,
    judging: Judging,
    settings: DiagnosisSettings,
    hypotheses: int,
    held: Residuals,
    vector: np.ndarray,
    basis: CalibrationBasis,
    critical: float,
    shares: int = 1,
) -> None:
    """Held-out figures and the acceptance tests of a fitted candidate, set on it.

    Parameters
    ----------
    candidate
        The fitted hypothesis (or pair) with its held-out replays.
    judging
        The held-out runs.
    settings
        ``worsen_limit``.
    hypotheses
        Hypotheses of the library (the fair share of one is 1 / that).
    held, vector
        The held-out residual without the candidate, and its normalised vector.
    basis
        Calibration directions around the parameters the candidate was fitted on top of.
    critical
        The evidence z the candidate must reach.
    shares
        Hypotheses the candidate holds: the fair share of the excess energy it must remove is
        that many times one hypothesis'.
    """
    sigma_x, sigma_i = judging.floors.sigma_position_m, judging.floors.sigma_current
    after = judging.residuals(candidate.replays)
    after_vector = judging.vector(after)
    before_rms = float(np.linalg.norm(vector))
    candidate.holdout_rms = float(np.linalg.norm(after_vector))
    candidate.reduction = 1.0 - candidate.holdout_rms / before_rms if before_rms else 0.0
    candidate.explained = math.sqrt(max(before_rms**2 - candidate.holdout_rms**2, 0.0))
    left_without = basis.correction(vector)[1]
    left_with = basis.correction(after_vector)[1]
    without, with_ = float(np.linalg.norm(left_without)), float(np.linalg.norm(left_with))
    candidate.reduction_beyond_calibration = 1.0 - with_ / without if without > 0 else 0.0
    candidate.evidence_z = improvement_z(left_without, left_with, judging.duration_s)
    candidate.critical_z = critical
    candidate.excess_share = excess_share(left_without, left_with)
    candidate.fair_share = shares * fair_share(hypotheses)
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
