"""Performance indices of a run record (paper section III.A, eqs. (10)-(11)).

Over a window [t0, tF] of the position-loop samples (spacing dt):

- ``E_pk_um``: max |e|, um (eq. (11));
- ``ITAE``: sum (t - t0) |e| dt, in um.s^2 (t from the window start);
- ``IAU``: sum |i| dt, in A.s (i: mean current command of each position period);
- ``rms_um`` and ``mean_abs_um``: RMS and mean of |e|, um;
- ``t_E_pk``: time of the peak, s; ``max_current_A``: max |i|, A.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

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


def compute_metrics(
    record: pd.DataFrame, window: tuple[float, float | None] = (0.0, None)
) -> Metrics:
    """Compute the indices of a record over ``window`` = (t0, tF) in s (tF None: to the end).

    Raises
    ------
    ValueError
        When the window holds fewer than two samples or the record has non-finite values.
    """
    t = record["t"].to_numpy()
    t0, t_end = window
    t_end = t[-1] if t_end is None else t_end
    inside = (t >= t0 - 1e-12) & (t <= t_end + 1e-12)
    if inside.sum() < 2:
        raise ValueError(f"metrics window [{t0}, {t_end}] s holds fewer than two samples")
    t = t[inside]
    error = np.abs(record["error"].to_numpy()[inside]) * UM_PER_M
    current = np.abs(record["current"].to_numpy()[inside])
    if not (np.all(np.isfinite(error)) and np.all(np.isfinite(current))):
        raise ValueError("the record holds non-finite errors or currents")
    dt = t[1] - t[0]
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
