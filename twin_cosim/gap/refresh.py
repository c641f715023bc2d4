"""Accepted effects refitted from a cold start once the forward rounds end.

An effect accepted in an early round was fitted while the effects found later were missing, and
the joint refits after each round move it only locally (a few least-squares steps): a Stribeck
curve fitted beside a missing inertia change can stay in the wrong valley of the rough training
cost for good, with about the right area under the curve and the wrong level and width (on a
transfer machine: 0.107 N.m at 0.87 rad/s for 0.160 N.m at 0.58 rad/s). So, before the backward
pass, each accepted effect fitted by least squares is refitted with the full global search
(:class:`~twin_cosim.gap.replay.FitTask` without a start) on top of the others as they are
now; the refit that leaves the least after the best calibration correction on the held-out
data replaces its effect when it leaves less than the model as it is. The selection runs it
when the forward rounds end and after a swap, before the next swaps are judged
(:meth:`twin_cosim.gap.selection.Selector.run`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.replay import FitTask, Replays, SimulateTask
from twin_cosim.gap.rounds import Accepted

if TYPE_CHECKING:
    from twin_cosim.gap.selector_view import SelectorView


def refresh(
    selector: SelectorView, accepted: list[Accepted], base: dict[str, float], replays: Replays
) -> tuple[dict[str, float], Replays] | None:
    """The model with its best cold refit of one accepted effect, or None when no refit
    leaves less than the model as it is.

    Parameters
    ----------
    selector
        The selection (pool, held-out runs, library, calibration directions).
    accepted
        The accepted effects; the replaced one's values are updated in place.
    base, replays
        FMU parameters of the accepted effects and their replays (training and held-out).

    Returns
    -------
    tuple or None
        FMU parameters and replays of the model with the refit (None: a single effect, or no
        refit leaves less).
    """
    if len(accepted) < 2:
        return None
    movable = [a for a in accepted if selector.library[a.name].kind == "continuous"]
    others = [
        {k: v for k, v in base.items() if k not in selector.library[a.name].sets} for a in movable
    ]
    fits = selector.tasks(
        "refresh_fits",
        [FitTask(a.name, o, a.context) for a, o in zip(movable, others, strict=True)],
    )
    trials = selector.tasks(
        "refresh_fits", [SimulateTask(f.overrides, with_training=True) for f in fits]
    )
    best = float(np.linalg.norm(selector.left(base, replays)))
    choice = None
    for effect, fit, trial in zip(movable, fits, trials, strict=True):
        left = float(np.linalg.norm(selector.left(fit.overrides, trial)))
        if left < best:
            best, choice = left, (effect, fit, trial)
    if choice is None:
        return None
    effect, fit, trial = choice
    effect.values = tuple(fit.values.values())
    return dict(fit.overrides), trial
