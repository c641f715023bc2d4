"""Performance indices of a run (paper section III.A, eqs. (10)-(11)): their one definition.

Over samples t_0 < ... < t_n of a window (the twin's position-loop samples, or a measured run's):

- ``E_pk_um``: max |e|, um (eq. (11));
- ``ITAE``: sum (t - t_0) |e| dt, in um.s^2 (t from the window start);
- ``IAU``: sum |i| dt, in A.s (i: mean current command of each position period);
- ``rms_um`` and ``mean_abs_um``: RMS and mean of |e|, um;
- ``t_E_pk``: time of the peak, s; ``max_current_A``: max |i|, A;
- ``settling_ms``: after each reversal or stop of the reference, the time until |e| lies within
  :data:`SETTLING_BAND_UM` and stays there for :data:`SETTLED_HOLD_S` (or up to the next
  reversal or stop), ms; the longest over them (None without one, or without the reference
  speed). A reversal or stop is where the reference speed reaches zero: it changes sign, or
  falls below :data:`REST_SPEED` (the interpolating spline leaves it only near zero at a dwell,
  never exactly zero). An error that does not settle before the next reversal or stop counts
  the whole time to it. E_pk does not see a slow tail after a reversal (friction and the
  integrator creeping the last microns in); this does.

The dt rule: dt is the median spacing of the samples, median(diff(t)) in s (the sample period of
a uniform grid; robust to a jittered or gapped time column of a measured run). The sums are
rectangle rules over the samples with that dt.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from twin_cosim.run_record import RunRecord

UM_PER_M = 1e6
SETTLING_BAND_UM = 1.0  # um: the error band of the settling time
REST_SPEED = 1e-5  # m/s: the reference is at rest below this (0.6 mm/min)
SETTLED_HOLD_S = 0.02  # s: the error stays within the band this long to count as settled


@dataclass(frozen=True)
class Metrics:
    """Indices of one run; see the module docstring for definitions and units."""

    E_pk_um: float
    ITAE: float
    IAU: float
    rms_um: float
    mean_abs_um: float
    t_E_pk: float
    max_current_A: float
    settling_ms: float | None = None

    def as_dict(self) -> dict[str, float]:
        """The indices by name."""
        return asdict(self)


def sample_period(t: np.ndarray) -> float:
    """The dt rule of the indices: the median spacing of the sample times ``t`` (s)."""
    return float(np.median(np.diff(t)))


def indices(
    t: np.ndarray,
    error: np.ndarray,
    current: np.ndarray,
    v_ref: np.ndarray | None = None,
    band_um: float = SETTLING_BAND_UM,
) -> Metrics:
    """The indices of samples at times ``t`` (s) of the position error (m) and current (A);
    the settling time too with the reference speed ``v_ref`` (m/s), to ``band_um`` (um).

    Raises
    ------
    ValueError
        When there are fewer than two samples, the arrays differ in length, or hold non-finite
        values.
    """
    t = np.asarray(t, dtype=np.float64)
    error = np.abs(np.asarray(error, dtype=np.float64)) * UM_PER_M
    current = np.abs(np.asarray(current, dtype=np.float64))
    if len(t) < 2 or not len(t) == len(error) == len(current):
        raise ValueError(
            f"metrics need two or more samples of t, error and current of one length, got "
            f"{len(t)}, {len(error)}, {len(current)}"
        )
    if not (np.all(np.isfinite(error)) and np.all(np.isfinite(current))):
        raise ValueError("the record holds non-finite errors or currents")
    dt = sample_period(t)
    peak = int(np.argmax(error))
    return Metrics(
        E_pk_um=float(error[peak]),
        ITAE=float(np.sum((t - t[0]) * error) * dt),
        IAU=float(np.sum(current) * dt),
        rms_um=float(np.sqrt(np.mean(error**2))),
        mean_abs_um=float(np.mean(error)),
        t_E_pk=float(t[peak]),
        max_current_A=float(current.max()),
        settling_ms=None if v_ref is None else settling_time_ms(t, error, v_ref, band_um),
    )


def settling_time_ms(
    t: np.ndarray, error_um: np.ndarray, v_ref: np.ndarray, band_um: float = SETTLING_BAND_UM
) -> float | None:
    """The longest time (ms) from a reversal or stop of the reference until |error| (um) lies
    within ``band_um`` for :data:`SETTLED_HOLD_S` (or up to the next one); None when the
    reference never reverses nor stops (module docstring)."""
    v = np.asarray(v_ref, dtype=np.float64)
    moving = np.abs(v) >= REST_SPEED
    stops = moving[:-1] & ~moving[1:]
    reversals = moving[:-1] & moving[1:] & (np.sign(v[:-1]) != np.sign(v[1:]))
    events = np.flatnonzero(stops | reversals) + 1  # the first sample at or past zero speed
    inside = np.abs(error_um) <= band_um
    longest = None
    for i, start in enumerate(events):
        end = int(events[i + 1]) if i + 1 < len(events) else len(t)
        settled = end - 1  # none found: the whole time to the next event, a lower bound
        for k in np.flatnonzero(inside[start:end]) + start:
            hold = np.searchsorted(t, t[k] + SETTLED_HOLD_S, side="right")
            if inside[k : min(hold, end)].all():
                settled = int(k)
                break
        elapsed = (t[settled] - t[start - 1]) * 1e3
        longest = elapsed if longest is None else max(longest, elapsed)
    return None if longest is None else float(longest)


def compute_metrics(record: RunRecord, window: tuple[float, float | None] = (0.0, None)) -> Metrics:
    """Compute the indices of a record over ``window`` = (t0, tF) in s (tF None: to the end).

    Raises
    ------
    ValueError
        When the window holds fewer than two samples or the record has non-finite values.
    """
    t = np.asarray(record["t"])
    t0, t_end = window
    t_end = t[-1] if t_end is None else t_end
    inside = (t >= t0 - 1e-12) & (t <= t_end + 1e-12)
    if inside.sum() < 2:
        raise ValueError(f"metrics window [{t0}, {t_end}] s holds fewer than two samples")
    v_ref = np.asarray(record["v_ref"])[inside] if "v_ref" in record.columns else None
    return indices(
        t[inside],
        np.asarray(record["error"])[inside],
        np.asarray(record["current"])[inside],
        v_ref,
    )


def compare_with_measured(
    record: RunRecord, t: np.ndarray, x: np.ndarray, current: np.ndarray
) -> dict[str, float]:
    """Replay against a measured run sampled at ``t`` (s): position x (m), current or command.

    Returns the RMS and maximum position gap (um), the relative position error
    ||x_sim - x|| / ||x|| (%) and the relative error of the current or drive command (%), the
    benchmark's figures of merit (eq. (11) of the EMPS description).
    """
    x_sim = np.interp(t, np.asarray(record["t"]), np.asarray(record["x"]))
    i_sim = np.interp(t, np.asarray(record["t"]), np.asarray(record["current"]))
    gap = x_sim - x
    return {
        "position_rms_gap_um": float(np.sqrt(np.mean(gap**2)) * UM_PER_M),
        "position_max_gap_um": float(np.max(np.abs(gap)) * UM_PER_M),
        "position_relative_error_pct": float(100 * np.linalg.norm(gap) / np.linalg.norm(x)),
        "current_relative_error_pct": float(
            100 * np.linalg.norm(i_sim - current) / np.linalg.norm(current)
        ),
    }
