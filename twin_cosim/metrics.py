"""Performance indices of a run (paper section III.A, eqs. (10)-(11)): their one definition.

Over samples t_0 < ... < t_n of a window (the twin's position-loop samples, or a measured run's):

- ``E_pk_um``: max |e|, um (eq. (11));
- ``ITAE``: sum (t - t_0) |e| dt, in um.s^2 (t from the window start);
- ``IAU``: sum |i| dt, in A.s (i: mean current command of each position period);
- ``rms_um`` and ``mean_abs_um``: RMS and mean of |e|, um;
- ``t_E_pk``: time of the peak, s; ``max_current_A``: max |i|, A.

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

    def as_dict(self) -> dict[str, float]:
        """The indices by name."""
        return asdict(self)


def sample_period(t: np.ndarray) -> float:
    """The dt rule of the indices: the median spacing of the sample times ``t`` (s)."""
    return float(np.median(np.diff(t)))


def indices(t: np.ndarray, error: np.ndarray, current: np.ndarray) -> Metrics:
    """The indices of samples at times ``t`` (s) of the position error (m) and current (A).

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
    )


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
    return indices(
        t[inside], np.asarray(record["error"])[inside], np.asarray(record["current"])[inside]
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
