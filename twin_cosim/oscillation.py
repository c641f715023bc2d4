"""Sustained oscillation of a closed-loop run: a limit cycle of the error, a chattering current.

A loop that oscillates may stay inside the divergence band (Kp_pos = 5000 on reference 1: a
+/-0.9 mm limit cycle at about 27 Hz, E_pk 954 um) or keep a small error while its current
chatters (Kp_vel = 30: the current reverses at every sample). Both show where the reference
holds still or moves at constant speed, after the transients of its last change have had
:data:`SETTLE_S` to decay:

- a limit cycle: the error's RMS about its mean over :data:`ERROR_WINDOW_S` is at least
  :data:`LIMIT_CYCLE_SHARE` of the run's E_pk (and at least :data:`LIMIT_CYCLE_FLOOR_UM`);
  a settled loop holds its error there (0.2-0.8 % of E_pk on the shipped scenarios with the
  paper's sets and on the EMPS replay; 36-70 % in the limit cycles);
- chattering: the current's RMS about its mean over :data:`CURRENT_WINDOW_S` is at least
  :data:`CHATTER_SHARE` of the current limit (at most 0.06 % with the paper's sets, 2.7-3.2 %
  with Kp_vel = 30).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from twin_cosim.run_record import RunRecord

SETTLE_S = 0.1  # time after a change of the reference's acceleration before a phase counts
STEADY_ACCELERATION = 1e-6  # m/s^2: below this the reference holds still or moves evenly
ERROR_WINDOW_S = 0.1  # the error's oscillation is taken about its mean over this window
CURRENT_WINDOW_S = 0.005  # the current's chattering is taken about its mean over this window
LIMIT_CYCLE_SHARE = 0.1  # of E_pk
LIMIT_CYCLE_FLOOR_UM = 1.0
CHATTER_SHARE = 0.01  # of the current limit


@dataclass(frozen=True)
class Oscillation:
    """What of a run oscillates where the reference holds still or moves evenly.

    Attributes
    ----------
    steady_s : float
        Time of those phases, settled, s (0: the checks do not apply).
    error_um : float
        RMS of the error about its :data:`ERROR_WINDOW_S` mean there, um.
    current_a : float
        RMS of the current about its :data:`CURRENT_WINDOW_S` mean there, A.
    reversals_per_s : float
        Reversals of the current's slope there, per second.
    """

    steady_s: float
    error_um: float
    current_a: float
    reversals_per_s: float


def _moving_mean(values: np.ndarray, samples: int) -> np.ndarray:
    """Centred mean over ``samples`` samples (fewer at the ends)."""
    half = max(samples // 2, 0)
    cumulative = np.concatenate([[0.0], np.cumsum(values)])
    index = np.arange(len(values))
    low = np.maximum(index - half, 0)
    high = np.minimum(index + half + 1, len(values))
    return (cumulative[high] - cumulative[low]) / (high - low)


def settled_steady_phases(t: np.ndarray, v_ref: np.ndarray) -> np.ndarray:
    """Samples where the reference holds still or moves at constant speed, :data:`SETTLE_S`
    after its last change (boolean mask).

    Parameters
    ----------
    t
        Time, s (evenly sampled).
    v_ref
        Reference speed, m/s.
    """
    dt = float(t[1] - t[0])
    steady = np.abs(np.gradient(v_ref, dt)) < STEADY_ACCELERATION
    settle = max(int(round(SETTLE_S / dt)), 1)
    changing = np.concatenate([[0], np.cumsum(~steady)])
    recent = changing[1:] - changing[np.maximum(np.arange(len(t)) + 1 - settle, 0)]
    return steady & (recent == 0)


def measure_oscillation(
    t: np.ndarray, v_ref: np.ndarray, error: np.ndarray, current: np.ndarray
) -> Oscillation:
    """The oscillation of a run's error and current in its settled steady phases.

    Parameters
    ----------
    t
        Time, s (evenly sampled, at least two samples).
    v_ref
        Reference speed, m/s.
    error
        Position error, m.
    current
        Motor current, A.
    """
    dt = float(t[1] - t[0])
    steady = settled_steady_phases(t, v_ref)
    if not steady.any():
        return Oscillation(0.0, 0.0, 0.0, 0.0)
    wobble = error - _moving_mean(error, int(round(ERROR_WINDOW_S / dt)))
    chatter = current - _moving_mean(current, int(round(CURRENT_WINDOW_S / dt)))
    slope = np.sign(np.diff(current))
    reversals = (slope[1:] != slope[:-1]) & steady[2:]
    steady_s = float(steady.sum()) * dt
    return Oscillation(
        steady_s=steady_s,
        error_um=float(np.sqrt(np.mean(wobble[steady] ** 2))) * 1e6,
        current_a=float(np.sqrt(np.mean(chatter[steady] ** 2))),
        reversals_per_s=float(reversals.sum()) / steady_s,
    )


def oscillation_findings(
    oscillation: Oscillation, peak_um: float, current_limit: float
) -> list[str]:
    """The limit cycle and the chattering a run shows, as sentences (none: it settles).

    Parameters
    ----------
    oscillation
        What :func:`measure_oscillation` found.
    peak_um
        The run's E_pk, um.
    current_limit
        The drive's current limit, A.
    """
    found = []
    where = f"where the reference holds still or moves evenly ({oscillation.steady_s:.3g} s)"
    cycle_um = max(LIMIT_CYCLE_SHARE * peak_um, LIMIT_CYCLE_FLOOR_UM)
    if oscillation.steady_s > 0 and oscillation.error_um >= cycle_um:
        found.append(
            "the loop oscillates (a limit cycle): the error swings with "
            f"{oscillation.error_um:.3g} um RMS {where}, "
            f"{oscillation.error_um / peak_um:.0%} of E_pk {peak_um:.3g} um (a settled loop: "
            f"below {LIMIT_CYCLE_SHARE:.0%})"
        )
    chatter_a = CHATTER_SHARE * current_limit
    if oscillation.steady_s > 0 and oscillation.current_a >= chatter_a:
        found.append(
            f"the current chatters: it swings {oscillation.current_a:.3g} A RMS about its "
            f"{CURRENT_WINDOW_S * 1e3:g} ms mean {where} and reverses "
            f"{oscillation.reversals_per_s:.0f} times per second (a settled loop: below "
            f"{chatter_a:.3g} A, {CHATTER_SHARE:.0%} of the {current_limit:g} A limit)"
        )
    return found


def record_findings(record: RunRecord, current_limit: float) -> list[str]:
    """:func:`oscillation_findings` of a run's record (``t`` s, ``v_ref`` m/s, ``error`` m,
    ``current`` A) with its current limit (A)."""
    error = np.asarray(record["error"], dtype=float)
    oscillation = measure_oscillation(
        np.asarray(record["t"], dtype=float),
        np.asarray(record["v_ref"], dtype=float),
        error,
        np.asarray(record["current"], dtype=float),
    )
    return oscillation_findings(oscillation, float(np.abs(error).max()) * 1e6, current_limit)
