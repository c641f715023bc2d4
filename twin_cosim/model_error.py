"""The twin's own error, measured on runs it was not fitted to, and what it bounds in a prediction.

A diagnosis judges its calibrated twin on held-out runs. What the twin still misses there is
the discrepancy of the scale reading, dx(t) = x_machine - x_twin (m), and of the current,
di(t) = i_machine - i_twin (A): unmodelled effects, effects fitted off, and the machine's
measurement noise (the twin has none). On one run with one set of gains the tracking errors
differ by dx (the reference is the same), so a figure of merit of the machine lies within
these margins of the twin's (the triangle inequality; Cauchy-Schwarz for the integrals, over a
metrics window of length T from t_0; for the rectangle sums of :mod:`twin_cosim.metrics` over N
samples T is N dt, one sample more than the window's span)::

    E_pk = max |e|:              |E_pk,machine - E_pk,twin| <= max |dx|
    ITAE = int (t - t_0) |e| dt: |ITAE,machine - ITAE,twin| <= T^2 / sqrt(3) RMS(dx)
    IAU  = int |i| dt:           |IAU,machine - IAU,twin|   <= T RMS(di)

A prediction for other gains on another trajectory (the tuned set on the production run)
carries these margins over from the held-out runs: it assumes that what the twin misses is no
larger there. That is an assumption, not a bound: plausible where the held-out runs cover the
production run's regimes (speeds, reversals, dwells). It is what lets a prediction's interval
hold a machine whose diagnosis missed an effect or fitted one off, which an interval over the
fitted parameters alone cannot (docs/transfer.md: 5 of 5 drawn machines inside).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

UM_PER_M = 1e6
# Keys of a plant file's ``model_error`` section, each a figure in SI units
FIELDS = ("position_peak_m", "position_rms_m", "current_rms_A")


@dataclass(frozen=True)
class ModelError:
    """What a calibrated twin misses on its held-out runs.

    Attributes
    ----------
    position_peak_m : float
        The largest |x_machine - x_twin| over the held-out runs, m.
    position_rms_m : float
        RMS of x_machine - x_twin over the held-out runs, m.
    current_rms_A : float
        RMS of i_machine - i_twin over the held-out runs, A (in the unit of the drive command
        where the runs record a command instead, as EMPS's in V; IAU is then in V.s).
    """

    position_peak_m: float
    position_rms_m: float
    current_rms_A: float

    @classmethod
    def of_discrepancy(cls, position_m: np.ndarray, current_a: np.ndarray) -> ModelError:
        """From the discrepancies (machine minus twin) of the scale reading (m) and the current
        (A) on the held-out runs, their samples concatenated."""
        x = np.asarray(position_m, dtype=np.float64)
        i = np.asarray(current_a, dtype=np.float64)
        if x.size == 0 or i.size == 0 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(i))):
            raise ValueError("model error: the discrepancies must be non-empty and finite")
        return cls(
            position_peak_m=float(np.max(np.abs(x))),
            position_rms_m=float(np.sqrt(np.mean(x**2))),
            current_rms_A=float(np.sqrt(np.mean(i**2))),
        )

    def as_dict(self) -> dict[str, float]:
        """The plant file's ``model_error`` section."""
        return {name: float(getattr(self, name)) for name in FIELDS}

    def margins(self, window_s: float) -> dict[str, float]:
        """How far the machine's E_pk (um), ITAE (um.s^2) and IAU (A.s) may lie from the twin's
        over a metrics window of ``window_s`` seconds (the module's bounds)."""
        if not (math.isfinite(window_s) and window_s > 0.0):
            raise ValueError(f"model error: the metrics window must be > 0 s, got {window_s!r}")
        return {
            "E_pk_um": self.position_peak_m * UM_PER_M,
            "ITAE": window_s**2 / math.sqrt(3.0) * self.position_rms_m * UM_PER_M,
            "IAU": window_s * self.current_rms_A,
        }
