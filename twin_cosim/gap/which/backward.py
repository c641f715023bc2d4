"""The backward pass: effects that the joint model does not need are dropped.

When the forward rounds end, a
backward pass refits the model without each accepted effect in turn; an effect whose removal
does not hurt the held-out fit beyond the noise (its marginal evidence z below the quantile of
``acceptance_level`` shared by the accepted effects, or its marginal share of the energy above
the noise below the fair share) is dropped, the weakest first. Each kept
effect's marginal contribution in the joint model is reported.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.floors.evidence import critical_z, excess_share, fair_share, improvement_z
from twin_cosim.gap.which.replay import Replays, SimulateTask
from twin_cosim.gap.which.rounds import Accepted, Marginal

if TYPE_CHECKING:
    from twin_cosim.gap.which.selector_view import SelectorView


def without_each(
    selector: SelectorView, accepted: list[Accepted], start: Replays
) -> list[tuple[dict[str, float], Replays]]:
    """Per accepted effect (``selector``: the selection), the model refitted without it (FMU
    parameters, replays); the refits run at once. Without a single effect it is the nominal
    twin (``start``): the best calibration correction of its held-out residual gives
    calibration error every benefit of the doubt already."""
    if len(accepted) == 1:
        return [({}, start)]
    refits = selector.tasks(
        "backward_pass",
        [selector.refit_task(accepted[:j] + accepted[j + 1 :]) for j in range(len(accepted))],
    )
    withouts = selector.tasks(
        "backward_pass", [SimulateTask(r.overrides, with_training=True) for r in refits]
    )
    return [(r.overrides, w) for r, w in zip(refits, withouts, strict=True)]


def backward(
    selector: SelectorView,
    accepted: list[Accepted],
    base: dict[str, float],
    replays: Replays,
    start: Replays,
) -> tuple[list[Accepted], dict[str, float], Replays, list[Marginal], list[str]]:
    """Drop, weakest first, accepted effects whose removal does not hurt the held-out fit
    beyond the noise; the kept effects' marginal contributions. A single effect is kept: it
    passed the stricter test of its round.

    Parameters
    ----------
    selector
        The selection (pool, held-out runs, settings, hypothesis library).
    accepted
        The accepted effects, in the order accepted.
    base, replays
        FMU parameters of the accepted effects and their replays (training and held-out).
    start
        Replays of the nominal twin (the model without a single effect).

    Returns
    -------
    tuple
        The kept effects, their FMU parameters and replays, their marginal contributions and
        the names of the effects dropped.
    """
    duration, dropped = selector.judging.duration_s, []
    least_share = fair_share(len(selector.library))
    while accepted:
        with_all = selector.left(base, replays)
        trials = []
        for j, (overrides, without) in enumerate(without_each(selector, accepted, start)):
            left = selector.left(overrides, without)
            z, share = improvement_z(left, with_all, duration), excess_share(left, with_all)
            strength = min(
                z / critical_z(selector.settings.acceptance_level, len(accepted)),
                share / least_share,
            )
            marginal = Marginal(
                accepted[j].name,
                z,
                share,
                float(np.linalg.norm(left)),
                float(np.linalg.norm(with_all)),
            )
            trials.append((strength, j, overrides, without, marginal))
        weakest = min(trials, key=lambda trial: trial[0])
        if len(accepted) == 1 or weakest[0] >= 1.0:
            return accepted, base, replays, [trial[4] for trial in trials], dropped
        _, j, base, replays, _ = weakest
        dropped.append(accepted[j].name)
        accepted = accepted[:j] + accepted[j + 1 :]
    return accepted, base, replays, [], dropped
