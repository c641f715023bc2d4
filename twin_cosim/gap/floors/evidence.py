"""Statistical evidence from the held-out residual itself: is there a gap, does an effect help?

Residual vectors here are normalised (:func:`twin_cosim.gap.calibration.normalised_vector`): the
position and current residuals over the held-out samples, each divided by its noise floor, the
whole scaled so that the squared norm is the mean normalised energy; white noise at the floors
has a squared norm of 1.

**Is there a gap?** What the best calibration correction leaves, ``left``, against its
distribution under noise at the floors alone. Residuals are correlated in time (the closed loop
filters them), so the count of independent samples is the held-out duration over
:data:`EFFECTIVE_SAMPLE_SPACING_S` per signal; the squared norm of such noise has a relative
standard deviation of sqrt(2 / n_eff) (a scaled chi-square), and the gap is significant when
``left^2`` exceeds 1 by ``z`` of them, z the one-sided normal quantile of the level (and the
floors' own uncertainty, :data:`FLOOR_UNCERTAINTY`, is added to the allowance).

**Does an effect help?** The drop of the energy left after the best calibration correction,
D = |e0|^2 - |e1|^2 (e0 without the effect, e1 with it, both recalibrated), against what noise
at the floors can make of it: with c = e0 - e1 the change the effect predicts, D = 2 <e0, c> -
|c|^2, and noise n in e0 gives 2 <n, c> a standard deviation of 2 |c| / sqrt(2 n_eff) (n_eff
independent samples per signal). z = D / that is compared with the one-sided quantile at the
level divided by the number of hypotheses judged (Bonferroni): testing more candidates asks more
of each. Noise is not all that a wrong hypothesis can fit: the residual left by other effects is
structured, and a wrong hypothesis explains a little of it far beyond the noise. So an effect
must also explain at least its fair share of the excess energy above the noise,
D / (|e0|^2 - 1) >= 1 / m for m hypotheses judged (:func:`fair_share`): under no effect the
excess would have no reason to fall to one hypothesis more than to the others.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

EFFECTIVE_SAMPLE_SPACING_S = 0.01  # s: one independent residual sample per 10 ms
FLOOR_UNCERTAINTY = 0.1  # relative uncertainty of the floors' energy (robust spread estimates)


def critical_z(level: float, tests: int = 1) -> float:
    """One-sided normal quantile for ``level`` shared by ``tests`` tests (Bonferroni)."""
    return -NormalDist().inv_cdf(level / max(tests, 1))


def gap_threshold(duration_s: float, level: float) -> float:
    """The normalised RMS that noise at the floors stays below with probability 1 - level.

    Parameters
    ----------
    duration_s
        Held-out duration, s (summed over runs).
    level
        Significance level (one-sided).
    """
    n_eff = 2.0 * effective_samples(duration_s)  # two signals
    return math.sqrt(1.0 + FLOOR_UNCERTAINTY + critical_z(level) * math.sqrt(2.0 / n_eff))


def effective_samples(duration_s: float) -> float:
    """Independent residual samples per signal in ``duration_s`` (s) of held-out data."""
    return max(duration_s / EFFECTIVE_SAMPLE_SPACING_S, 1.0)


def improvement_z(before: np.ndarray, after: np.ndarray, duration_s: float) -> float:
    """Evidence (z) that ``after`` fits better than ``before`` beyond the noise.

    Parameters
    ----------
    before, after
        Normalised residual vectors left after the best calibration correction, without and
        with the effect.
    duration_s
        Held-out duration, s (summed over runs).
    """
    change = before - after
    drop = float(before @ before - after @ after)
    spread = 2.0 * float(np.linalg.norm(change)) / math.sqrt(2.0 * effective_samples(duration_s))
    if spread <= 0.0:
        return 0.0
    return drop / spread


def excess_share(before: np.ndarray, after: np.ndarray) -> float:
    """Share of the energy above the noise (|before|^2 - 1) that ``after`` removes."""
    excess = float(before @ before) - 1.0
    if excess <= 0.0:
        return 0.0
    return float(before @ before - after @ after) / excess


def fair_share(hypotheses: int) -> float:
    """The least share of the excess energy an effect must explain among ``hypotheses``."""
    return 1.0 / max(hypotheses, 1)
