"""The evidence of the held-out residual against its floors: what calibration error can
explain of it, whether what is left is a gap, and whether a change improves it beyond the noise.

**The normalised residual** (:func:`normalised_vector`): the position and current residuals over
the held-out samples, each divided by its noise floor, the whole scaled by 1 / sqrt(2 N) so that
the squared norm is the mean normalised energy (the norm is the normalised RMS); white noise at
the floors has a squared norm of 1.

**The calibration floor** (:class:`CalibrationBasis`, :func:`floor_of`). The nominal values of
the calibrated parameters (``calibrated`` in the model's card, :mod:`twin_cosim.plant_model`)
are known only to ``calibration_tolerance`` (3 %). Each is moved by +/- that tolerance and the
held-out runs replayed; half the difference of the two replays is its *calibration direction*,
the change of the twin's output per tolerance. The best calibration correction of a residual r
is the combination sum a_j c_j with every |a_j| <= 1 (bounded linear least squares,
``scipy.optimize.lsq_linear``, solved on the directions' QR factors: with C = QR,
|r - C a|^2 = |Q^T r - R a|^2 + |r|^2 - |Q^T r|^2, a problem of one row per parameter instead of
one per sample) closest to r; what it leaves is the part of the gap that calibration error
cannot explain, and a change counts only when it shrinks that part too. The correction is
fitted on the held-out data themselves: calibration error gets every benefit of the doubt,
bounded by the tolerance. Where this linear correction leaves a gap, the selection replays it and
re-linearises around the corrected parameters
(:meth:`twin_cosim.gap.which.replay_pool.ReplayPool.calibration`).

**Is there a gap?** What the best calibration correction leaves, ``left``, against its
distribution under noise at the floors alone. Residuals are correlated in time (the closed loop
filters them), so the count of independent samples is the held-out duration over
:data:`EFFECTIVE_SAMPLE_SPACING_S` per signal; the squared norm of such noise has a relative
standard deviation of sqrt(2 / n_eff) (a scaled chi-square), and the gap is significant when
``left^2`` exceeds 1 by ``z`` of them, z the one-sided normal quantile of the level (and the
floors' own uncertainty, :data:`FLOOR_UNCERTAINTY`, is added to the allowance).

**Does a change help?** The drop of the energy left after the best calibration correction,
D = |e0|^2 - |e1|^2 (e0 without the change, e1 with it, both recalibrated), against what noise
at the floors can make of it: with c = e0 - e1 the change predicted, D = 2 <e0, c> - |c|^2, and
noise n in e0 gives 2 <n, c> a standard deviation of 2 |c| / sqrt(2 n_eff) (n_eff independent
samples per signal). z = D / that is compared with the one-sided quantile at the level divided
by the number of changes judged (Bonferroni): testing more candidates asks more of each. Noise
is not all that a wrong hypothesis can fit: the residual left by other effects is structured,
and a wrong hypothesis explains a little of it far beyond the noise. So a change must also
explain at least its fair share of the excess energy above the noise, D / (|e0|^2 - 1) >= 1 / m
for m hypotheses (:func:`fair_share`): under no effect the excess would have no reason to fall
to one hypothesis more than to the others. The acceptance rule that asks these two tests is
:class:`twin_cosim.gap.which.acceptance.Acceptance`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from statistics import NormalDist

import numpy as np

from twin_cosim.gap.data.residuals import Residuals

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


def correlation_time(pieces: list[np.ndarray], dt: float) -> float:
    """The integral correlation time of a residual, s, at least
    :data:`EFFECTIVE_SAMPLE_SPACING_S`: per piece (each mean removed) dt (1 + 2 sum rho_k) over
    the lags before its autocorrelation rho first falls to zero, weighted by the pieces'
    lengths. White noise has dt; a slow wander (what a settling axis leaves at standstill)
    tenths of a second, and counting its samples as independent every 10 ms would overstate
    the evidence against it. It stands for the spectrum at zero frequency: against a wave of
    a few hertz it counts a red residual as somewhat more noise than it is there (by 1.7
    for a first-order wander against 4.3 Hz), on the side of dropping."""
    total, weight = 0.0, 0
    for piece in pieces:
        centred = np.asarray(piece, dtype=np.float64) - np.mean(piece)
        energy = float(centred @ centred)
        if centred.size < 2 or energy == 0.0:
            continue
        spectrum = np.fft.rfft(centred, 2 * centred.size)
        rho = np.fft.irfft(np.abs(spectrum) ** 2)[: centred.size] / energy
        first_zero = int(np.argmax(rho <= 0.0)) if np.any(rho <= 0.0) else rho.size
        total += centred.size * dt * (1.0 + 2.0 * float(np.sum(rho[1:first_zero])))
        weight += centred.size
    return max(total / weight if weight else 0.0, EFFECTIVE_SAMPLE_SPACING_S)


def improvement_z(
    before: np.ndarray, after: np.ndarray, duration_s: float, signals: int = 2
) -> float:
    """Evidence (z) that ``after`` fits better than ``before`` beyond the noise.

    Parameters
    ----------
    before, after
        Normalised residual vectors left after the best calibration correction, without and
        with the effect.
    duration_s
        Held-out duration, s (summed over runs), at one independent sample per
        :data:`EFFECTIVE_SAMPLE_SPACING_S` and signal.
    signals
        The signals the vectors hold (position and current: 2).
    """
    change = before - after
    drop = float(before @ before - after @ after)
    independent = signals * effective_samples(duration_s)
    spread = 2.0 * float(np.linalg.norm(change)) / math.sqrt(independent)
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


def normalised_vector(res: Residuals, sigma_x: float, sigma_i: float) -> np.ndarray:
    """The residual as one normalised vector whose norm is its normalised RMS."""
    scale = 1.0 / math.sqrt(2.0 * len(res.t))
    return np.concatenate([res.position / sigma_x, res.current / sigma_i]) * scale


@dataclass(frozen=True)
class CalibrationBasis:
    """Calibration directions of the twin around one parameter set.

    Attributes
    ----------
    names : list of str
        The calibrated parameters, in the order of the columns.
    directions : numpy.ndarray
        (samples, parameters): change of the normalised held-out output per +tolerance move.
    """

    names: list[str]
    directions: np.ndarray

    @cached_property
    def _factors(self) -> tuple[np.ndarray, np.ndarray]:
        """Q (samples, parameters) and R (parameters, parameters) of the directions."""
        return np.linalg.qr(self.directions, mode="reduced")

    def correction(
        self,
        residual: np.ndarray,
        bounds: tuple[np.ndarray | float, np.ndarray | float] = (-1.0, 1.0),
    ) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients a (tolerances, within ``bounds``: |a| <= 1 unless told) and what the
        best correction leaves of r."""
        from scipy.optimize import lsq_linear  # here: the replay workers import this module

        if self.directions.shape[1] == 0:
            return np.zeros(0), residual
        q, r = self._factors
        fit = lsq_linear(r, q.T @ residual, bounds=bounds)
        return fit.x, residual - self.directions @ fit.x

    def left_after(self, residual: np.ndarray) -> float:
        """Norm of what the best calibration correction leaves of a residual."""
        return float(np.linalg.norm(self.correction(residual)[1]))


@dataclass(frozen=True)
class CalibrationFloor:
    """The calibration floor of one residual.

    Attributes
    ----------
    before : float
        Normalised RMS of the residual.
    left : float
        Normalised RMS left after the best calibration correction.
    explained : float
        sqrt(before^2 - left^2): the normalised RMS calibration error can explain (the
        *calibration floor* an effect must go beyond).
    coefficients : dict
        The correction per calibrated parameter, in tolerances (-1 to 1).
    """

    before: float
    left: float
    explained: float
    coefficients: dict[str, float]


def floor_of(basis: CalibrationBasis, residual: np.ndarray) -> CalibrationFloor:
    """The calibration floor of a normalised residual vector."""
    coefficients, left_vector = basis.correction(residual)
    before = float(np.linalg.norm(residual))
    left = float(np.linalg.norm(left_vector))
    return CalibrationFloor(
        before,
        left,
        math.sqrt(max(before**2 - left**2, 0.0)),
        {n: float(a) for n, a in zip(basis.names, coefficients, strict=True)},
    )
