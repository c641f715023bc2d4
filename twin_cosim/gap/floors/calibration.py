"""The calibration floor: how much of a held-out residual calibration error alone can explain.

The nominal values of the calibrated parameters (``calibrated`` in the model's card,
:mod:`twin_cosim.plant_model`) are known only to ``calibration_tolerance`` (3 %). Each is moved by
+/- that tolerance and the held-out runs replayed; half the difference of the two replays is its
*calibration direction*, the change of the twin's output per tolerance. The best calibration
correction of a residual r is the combination sum a_j c_j with every |a_j| <= 1 (bounded linear
least squares, ``scipy.optimize.lsq_linear``, solved on the directions' QR factors: with C = QR,
|r - C a|^2 = |Q^T r - R a|^2 + |r|^2 - |Q^T r|^2, a problem of one row per parameter instead of
one per sample) closest to r; what it leaves is the part of the gap
that calibration error cannot explain, and an effect is accepted only when it shrinks that part too.
The correction is fitted on the held-out data themselves: calibration error gets every benefit of
the doubt, bounded by the tolerance.

Residual vectors here are normalised: position residual / sigma_x and current residual / sigma_i
over the held-out samples, scaled by 1 / sqrt(2 N), so that the norm is the normalised RMS (1 for
noise at the floors).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import lsq_linear

from twin_cosim.gap.data.residuals import Residuals


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

    def correction(self, residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients a (|a| <= 1, tolerances) and what the best correction leaves of r."""
        if self.directions.shape[1] == 0:
            return np.zeros(0), residual
        q, r = self._factors
        fit = lsq_linear(r, q.T @ residual, bounds=(-1.0, 1.0))
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
