"""What motion a diagnosis needs in its training and its held-out data.

The effects of the library show where the drive moves and where it turns: friction, inertia and
stiffness effects while moving (acceleration or constant velocity), Stribeck friction, backlash
and friction asymmetry at a reversal. Training data without them cannot fit those effects, and
held-out data without them cannot judge them: a time split of a run cut short, or a held-out run
that only dwells, would accept or reject effects on nothing. Each of the two data sets must hold

- motion: samples of the acceleration or constant-velocity regime, and
- a reversal: a motion start against the previous direction of motion (the reversal regime of
  :mod:`twin_cosim.gap.regimes`),

or the diagnosis is refused naming the files and what is missing.
"""

from __future__ import annotations

import numpy as np

from twin_cosim.gap import regimes as regime_model
from twin_cosim.measured import MeasuredDataError, MeasuredRun
from twin_cosim.reference import ReferenceGrid

NEEDED = {
    "motion (acceleration or constant velocity)": (
        regime_model.ACCELERATION,
        regime_model.CONSTANT_VELOCITY,
    ),
    "reversal": (regime_model.REVERSAL,),
}


def missing_regimes(runs: list[MeasuredRun], grids: list[ReferenceGrid]) -> list[str]:
    """What of :data:`NEEDED` none of the runs holds (each run against its reference grid)."""
    present: set[int] = set()
    for run, grid in zip(runs, grids, strict=True):
        v_ref = np.interp(run.t, grid.time, grid.velocity)
        a_ref = np.interp(run.t, grid.time, grid.acceleration)
        present.update(np.unique(regime_model.classify_regimes(run.t, v_ref, a_ref)).tolist())
    return [need for need, codes in NEEDED.items() if not present.intersection(codes)]


def check_coverage(
    runs: list[MeasuredRun], grids: list[ReferenceGrid], role: str, how: str
) -> None:
    """Refuse data that miss a regime the diagnosis needs.

    Parameters
    ----------
    runs
        The training or the held-out data.
    grids
        The reference each run follows.
    role
        ``"training"`` or ``"held-out"``.
    how
        How the data were chosen, for the message (e.g. ``"time split at t = 6.2 s"``).

    Raises
    ------
    MeasuredDataError
        Naming the files, the span of each, and what is missing.
    """
    missing = missing_regimes(runs, grids)
    if not missing:
        return
    spans = ", ".join(f"{r.source} (t = {r.t[0]:.3g} to {r.t[-1]:.3g} s)" for r in runs)
    raise MeasuredDataError(
        f"{spans}: the {role} data ({how}) hold no {' and no '.join(missing)}; a diagnosis "
        "needs moves and reversals in its training and in its held-out data: record runs "
        "that move and reverse in each part (the whole reference of a scenario that does)"
    )
