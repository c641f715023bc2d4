"""The two-mass parameters fitted to a plant FRF: J_M, J_L, f_1, D_1, viscous friction, and the
drive's delay and current-loop lag.

Model: motor speed over motor torque, eq. (3) with viscous friction F_V on the load
(:meth:`~twin_cosim.frequency.two_mass.TwoMass.speed_per_torque`), times
exp(-j w tau) / (1 + j w tau_i) for what the measurement holds of the drive: a delay tau (its
sampling and computation) and a first-order current loop tau_i. Fitted in the log of
the ratio model / measurement, whose real part is the magnitude error (in nepers) and imaginary
part the phase error (rad), so that every line counts alike at any level; each line is weighted
by its coherence gamma^2 / (1 - gamma^2) (its signal-to-noise ratio, capped), or equally
without one. The parameters are fitted in logarithms (J_M, J_L, f_1, D_1) and in natural
scales (F_V over J w_01, tau and tau_i in ms), with bounds; the fit starts from what the curve shows
(:func:`first_guess`) with several damping ratios and keeps the best.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from twin_cosim.frequency.two_mass import TwoMass

MAX_WEIGHT = 1.0e3  # the largest coherence weight, gamma^2 / (1 - gamma^2)
DAMPING_STARTS = (0.05, 0.15, 0.4)
DELAY_BOUNDS_MS = (-0.5, 20.0)
LAG_BOUND_MS = 20.0


@dataclass(frozen=True)
class TwoMassFit:
    """The fitted two-mass plant and how well it fits.

    Attributes
    ----------
    plant : TwoMass
        J_M, J_L, coupling and viscous friction (torque constant 1: the FRF is per N.m).
    delay_s : float
        Fitted delay, s.
    lag_s : float
        Fitted current-loop time constant, s.
    rms_db : float
        Weighted RMS magnitude error over the fitted lines, dB.
    rms_deg : float
        Weighted RMS phase error, degrees.
    lines : int
        Lines fitted.
    """

    plant: TwoMass
    delay_s: float
    lag_s: float
    rms_db: float
    rms_deg: float
    lines: int

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The fitted model at ``frequency_hz`` (Hz), delay included, rad/s per N.m."""
        return _drive(self.plant, self.delay_s, self.lag_s, np.asarray(frequency_hz, float))

    def parameters(self) -> dict[str, float]:
        """The FMU parameters it gives (drive2mass names, SI units)."""
        return {
            "motor_inertia": float(self.plant.motor_inertia),
            "load_inertia": float(self.plant.load_inertia),
            "resonance_frequency": float(self.plant.antiresonance_hz),
            "damping_ratio": float(self.plant.damping_ratio),
            "viscous_friction": float(self.plant.viscous_friction),
        }


def _plant(theta: np.ndarray, scale: float) -> tuple[TwoMass, float, float]:
    """The plant, delay (s) and lag (s) of the fit's parameter vector."""
    j_m, j_l, f_1, d_1 = (float(v) for v in np.exp(theta[:4]))
    viscous = float(theta[4]) * scale
    plant = TwoMass.from_paper(j_m, j_l, f_1, d_1, viscous_friction=viscous)
    return plant, float(theta[5]) * 1e-3, float(theta[6]) * 1e-3


def _drive(plant: TwoMass, delay: float, lag: float, frequency_hz: np.ndarray) -> np.ndarray:
    """Eq. (3) with viscous friction, the delay and the lag, rad/s per N.m."""
    s = 2j * np.pi * frequency_hz
    return plant.speed_per_torque(frequency_hz) * np.exp(-s * delay) / (1.0 + s * lag)


def model(theta: np.ndarray, scale: float, frequency_hz: np.ndarray) -> np.ndarray:
    """The fitted model's response at ``frequency_hz`` (rad/s per N.m, complex)."""
    return _drive(*_plant(theta, scale), frequency_hz)


def first_guess(frequency_hz: np.ndarray, response: np.ndarray) -> tuple[float, float, float]:
    """J_M, J_L (kg.m2) and f_1 (Hz) from the curve w |H|: its low and high asymptotes
    1 / (J_M + J_L) and 1 / J_M, its minimum (antiresonance) and the maximum above it."""
    g = 2 * np.pi * frequency_hz * np.abs(response)
    n = max(2, len(g) // 10)
    total = 1.0 / np.median(g[:n])
    low = int(np.argmin(g[n:-n])) + n if len(g) > 2 * n + 2 else int(np.argmin(g))
    high = low + int(np.argmax(g[low:]))
    ratio = (frequency_hz[high] / frequency_hz[low]) ** 2
    if not 1.05 < ratio < 100.0:  # no clear pair: from the asymptotes alone
        ratio = min(max(total * np.median(g[-n:]), 1.05), 100.0)
    j_m = total / ratio
    return j_m, total - j_m, float(frequency_hz[low])


def fit_two_mass(
    frequency_hz: np.ndarray, response: np.ndarray, coherence: np.ndarray | None = None
) -> TwoMassFit:
    """Fit the two-mass model to a plant FRF (motor speed over motor torque).

    Parameters
    ----------
    frequency_hz
        Frequencies of the lines to fit, Hz.
    response
        The measured response, rad/s per N.m, complex.
    coherence
        gamma^2 per line, or None (equal weights).
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    h = np.asarray(response, dtype=np.complex128)
    if coherence is None:
        weights = np.ones(len(f))
    else:
        gamma = np.clip(coherence, 0.0, 1.0)
        weights = np.minimum(gamma / np.maximum(1.0 - gamma, 1.0 / MAX_WEIGHT), MAX_WEIGHT)
    root = np.sqrt(weights / weights.mean())
    j_m, j_l, f_1 = first_guess(f, h)
    scale = (j_m + j_l) * 2 * np.pi * f_1  # N.m.s/rad: viscous friction in these units

    def residual(theta: np.ndarray) -> np.ndarray:
        error = np.log(model(theta, scale, f) / h)
        return np.concatenate([root * error.real, root * error.imag])

    lower = np.log([j_m / 20, j_l / 20, f[0] / 2, 1e-3]).tolist()
    lower += [0.0, DELAY_BOUNDS_MS[0], 0.0]
    upper = np.log([j_m * 20, j_l * 20, f[-1] * 2, 5.0]).tolist()
    upper += [10.0, DELAY_BOUNDS_MS[1], LAG_BOUND_MS]
    best = None
    for damping in DAMPING_STARTS:
        start = np.array([*np.log([j_m, j_l, f_1, damping]), 0.0, 0.0, 0.0])
        start = np.clip(start, np.array(lower) + 1e-9, np.array(upper) - 1e-9)
        found = least_squares(residual, start, bounds=(lower, upper), x_scale="jac")
        if best is None or found.cost < best.cost:
            best = found
    plant, delay, lag = _plant(best.x, scale)
    error = np.log(model(best.x, scale, f) / h)
    return TwoMassFit(
        plant=plant,
        delay_s=delay,
        lag_s=lag,
        rms_db=float(np.sqrt(np.average(error.real**2, weights=weights)) * 20 / math.log(10)),
        rms_deg=float(np.degrees(np.sqrt(np.average(error.imag**2, weights=weights)))),
        lines=len(f),
    )
