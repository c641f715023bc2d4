"""Accepted effects refitted from a cold start once the forward rounds end.

An effect accepted in an early round was fitted while the effects found later were missing, and
the joint refits after each round move it only locally (a few least-squares steps): a Stribeck
curve fitted beside a missing inertia change can stay in the wrong valley of the rough training
cost for good, with about the right area under the curve and the wrong level and width (on a
transfer machine: 0.107 N.m at 0.87 rad/s for 0.160 N.m at 0.58 rad/s). So, before the backward
pass, each accepted effect fitted by least squares is refitted from a search over its whole
range (:class:`~twin_cosim.gap.replay.FitTask` without a start: the global search of round 1,
and for a level and a shape parameter such as the Stribeck level and speed also the profile
over the shape, :func:`~twin_cosim.gap.replay.profile_start`: the two searches stop in
different valleys of a rough cost) on top of the others as they are now; the
refit that leaves the least after the best calibration correction on the held-out
data replaces its effect when it leaves less than the model as it is. The selection runs it
when the forward rounds end and after a swap, before the next swaps are judged
(:meth:`twin_cosim.gap.selection.Selector.run`).

The refit's gain is judged as a round's candidate is (:class:`~twin_cosim.gap.rounds.Refit`):
its evidence z beyond the noise against the one-sided quantile of ``acceptance_level`` shared
by the refits tried, and its share of the energy above the noise against the fair share. Only
a refit that passes lets the forward rounds resume: a refit that moves a curve within the
noise leaves the next round the same candidates to judge against nearly the same residual
(on the issue's three-effect machine: one round more, 230 replays, nothing accepted).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.floors.evidence import critical_z, excess_share, fair_share, improvement_z
from twin_cosim.gap.which.replay import FitTask, Replays, SimulateTask, shape_index
from twin_cosim.gap.which.rounds import Accepted, Refit

if TYPE_CHECKING:
    from twin_cosim.gap.which.selector_view import SelectorView


def refresh(
    selector: SelectorView, accepted: list[Accepted], base: dict[str, float], replays: Replays
) -> tuple[dict[str, float], Replays, Refit] | None:
    """The model with its best cold refit of one accepted effect and the refit's record, or
    None when no refit leaves less than the model as it is.

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
        FMU parameters and replays of the model with the refit, and its record (None: a single
        effect, or no refit leaves less).
    """
    if len(accepted) < 2:
        return None
    library = selector.library
    movable = [a for a in accepted if library[a.name].kind == "continuous"]
    tries = [(a, False) for a in movable] + [
        (a, True) for a in movable if shape_index(library[a.name]) is not None
    ]
    fits = selector.tasks(
        "refresh_fits",
        [
            FitTask(
                a.name,
                {k: v for k, v in base.items() if k not in library[a.name].sets},
                a.context,
                profile=profile,
            )
            for a, profile in tries
        ],
    )
    trials = selector.tasks(
        "refresh_fits", [SimulateTask(f.overrides, with_training=True) for f in fits]
    )
    before = selector.left(base, replays)
    left_before = float(np.linalg.norm(before))
    best, choice = left_before, None
    for (effect, _), fit, trial in zip(tries, fits, trials, strict=True):
        after = selector.left(fit.overrides, trial)
        left = float(np.linalg.norm(after))
        if left < best:
            best, choice = left, (effect, fit, trial, after)
    if choice is None:
        return None
    effect, fit, trial, after = choice
    record = Refit(
        effect.name,
        effect.values,
        tuple(fit.values.values()),
        left_before,
        best,
        improvement_z(before, after, selector.judging.duration_s),
        critical_z(selector.settings.acceptance_level, len(tries)),
        excess_share(before, after),
        fair_share(len(library)),
    )
    effect.values = record.values_after
    return dict(fit.overrides), trial, record
