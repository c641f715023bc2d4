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
D = |e0|^2 - |e1|^2 (e0 without the effect, e1 with it, both recalibrated), against the spread
that the noise left with the effect gives it: with c = e0 - e1 the change the effect predicts,
D = 2 <e1, c> + |c|^2, and over blocks of :data:`BLOCK_S` (longer than the residual's correlation
time, so blocks are nearly independent) the standard deviation of 2 <e1, c> is estimated by
sqrt(sum_b (2 <e1_b, c_b>)^2) from the residual itself, whatever its spectrum. z = D / that is
compared with the one-sided quantile at the level divided by the number of hypotheses judged
(Bonferroni): testing more candidates asks more of each.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

EFFECTIVE_SAMPLE_SPACING_S = 0.01  # s: one independent residual sample per 10 ms
BLOCK_S = 0.05  # s: blocks of the held-out residual for the spread of an improvement
FLOOR_UNCERTAINTY = 0.1  # relative uncertainty of the floors' energy (robust spread estimates)


def critical_z(level: float, tests: int = 1) -> float:
    """One-sided normal quantile for ``level`` shared by ``tests`` tests (Bonferroni)."""
    return float(norm.isf(level / max(tests, 1)))


def gap_threshold(duration_s: float, level: float) -> float:
    """The normalised RMS that noise at the floors stays below with probability 1 - level.

    Parameters
    ----------
    duration_s
        Held-out duration, s (summed over runs).
    level
        Significance level (one-sided).
    """
    n_eff = max(2.0 * duration_s / EFFECTIVE_SAMPLE_SPACING_S, 1.0)  # two signals
    return math.sqrt(1.0 + FLOOR_UNCERTAINTY + critical_z(level) * math.sqrt(2.0 / n_eff))


def block_labels(samples: int, dt: float) -> np.ndarray:
    """Block of each entry of a normalised vector [position (samples), current (samples)].

    Parameters
    ----------
    samples
        Held-out samples (the length of each half).
    dt
        Sample period, s.
    """
    per_block = max(int(round(BLOCK_S / dt)), 1)
    labels = np.arange(samples) // per_block
    return np.concatenate([labels, labels])


def improvement_z(before: np.ndarray, after: np.ndarray, blocks: np.ndarray) -> float:
    """Evidence (z) that ``after`` fits better than ``before`` beyond the noise left.

    Parameters
    ----------
    before, after
        Normalised residual vectors left after the best calibration correction, without and
        with the effect.
    blocks
        Block label of each entry (:func:`block_labels`).
    """
    change = before - after
    drop = float(before @ before - after @ after)
    spread = np.bincount(blocks, weights=2.0 * after * change)
    variance = float(spread @ spread)
    if variance <= 0.0:
        return math.inf if drop > 0.0 else 0.0
    return drop / math.sqrt(variance)
