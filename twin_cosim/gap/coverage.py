"""What motion a diagnosis needs in its training and its held-out data.

The effects of the library show where the drive moves and where it turns: friction, inertia and
stiffness effects while moving, Stribeck friction, backlash and friction asymmetry at a reversal.
Training data without them cannot fit those effects, and held-out data without them cannot
judge them: a time split of a run that only dwells in one half, or a held-out run that never
turns, would accept or reject effects on nothing. Each of the two data sets must hold

- motion: a stroke of the reference (:func:`twin_cosim.gap.regimes.strokes`: one direction,
  more than 1 um), and
- a reversal: two strokes of one run in opposite directions, one after the other (with or
  without a dwell between them),

or the diagnosis is refused naming the files and what is missing.
"""

from __future__ import annotations

import numpy as np

from twin_cosim.gap import regimes as regime_model
from twin_cosim.measured import MeasuredDataError, MeasuredRun
from twin_cosim.reference import ReferenceGrid

MOTION = "motion"
REVERSAL = "reversal"


def missing_regimes(runs: list[MeasuredRun], grids: list[ReferenceGrid]) -> list[str]:
    """What of motion and a reversal none of the runs holds (each against its reference)."""
    moves = reverses = False
    still = regime_model.RegimeSettings().v_still
    for run, grid in zip(runs, grids, strict=True):
        v_ref = np.interp(run.t, grid.time, grid.velocity)
        direction = np.where(np.abs(v_ref) > still, np.sign(v_ref), 0)
        position = np.interp(run.t, grid.time, grid.position)
        signs = [sign for _, _, sign in regime_model.strokes(direction, position)]
        moves |= bool(signs)
        reverses |= any(a != b for a, b in zip(signs[:-1], signs[1:], strict=True))
    return [need for need, held in ((MOTION, moves), (REVERSAL, reverses)) if not held]


def check_coverage(
    runs: list[MeasuredRun], grids: list[ReferenceGrid], role: str, how: str
) -> None:
    """Refuse data that miss motion or a reversal.

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
