"""Swaps: an accepted effect replaced by a rival that passed the same round.

Forward selection accepts the best passing hypothesis of a round by training BIC, and an effect
in the wrong place can win it: a stiffness change shifts the resonance, and a backlash or an
inertia change fitted alone takes that up first (on random tune machines: an inertia change of
+21 % fitted for a stiffness change of -35 %, one of -23 % for +35 %). Once it is in, the
right effect fitted on top of it is under the tolerance or its fair share, and the joint
refits only move the accepted effects locally.

So when the forward rounds end, each accepted effect is replaced in turn by each *rival*: a
hypothesis that passed every acceptance test in the round that accepted the effect, outside its
look-alike group and not accepted itself. The rival is fitted on top of the other accepted
effects (from its fit of that round, as later rounds start), then all effects of the swapped
model are refitted together (as after an accepted effect: the others were fitted beside the
effect taken out), the better of the two on the held-out data is judged against the model as
it is with the tests a round's candidates pass (:func:`twin_cosim.gap.judging.judge`):
it cuts the held-out normalised RMS, its evidence z beyond the noise after the best calibration
correction reaches the one-sided quantile of ``acceptance_level`` shared by the swaps tried
(Bonferroni), it removes at least its fair share of the energy above the noise that the model
leaves, a change of a calibrated parameter exceeds the tolerance, and neither signal gets worse.
The best passing swap by training BIC is made.
An effect swapped out is never swapped back in (the criterion falls at every swap made, and the
swaps end).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.floors.evidence import critical_z
from twin_cosim.gap.which.acceptance import judge
from twin_cosim.gap.which.replay import FitResult, FitTask, Replays, SimulateTask
from twin_cosim.gap.which.rounds import Accepted, Candidate, Round, Swap, bic

if TYPE_CHECKING:
    from twin_cosim.gap.which.selector_view import SelectorView


def rivals(
    rounds: list[Round], accepted: list[Accepted], swapped_out: set[str]
) -> list[tuple[int, Candidate]]:
    """Per accepted effect (its index), the hypotheses that passed its round beside it.

    Parameters
    ----------
    rounds
        The rounds so far (``Accepted.round`` indexes them from 1).
    accepted
        The accepted effects.
    swapped_out
        Effects taken out by earlier swaps (never rivals again).
    """
    taken = {name for a in accepted for name in a.group}
    found = []
    for j, effect in enumerate(accepted):
        if not 1 <= effect.round <= len(rounds):
            continue
        for c in rounds[effect.round - 1].candidates:
            if c.passes and c.name not in taken and c.name not in swapped_out:
                found.append((j, c))
    return found


def swap(
    selector: SelectorView,
    rounds: list[Round],
    accepted: list[Accepted],
    base: dict[str, float],
    replays: Replays,
    records: list[Swap],
) -> tuple[dict[str, float], Replays] | None:
    """The model with its best passing swap made, or None when no swap passes.

    Parameters
    ----------
    selector
        The selection (pool, held-out runs, settings, hypothesis library).
    rounds
        The rounds so far.
    accepted
        The accepted effects; the swapped one is replaced in place.
    base, replays
        FMU parameters of the accepted effects and their replays (training and held-out).
    records
        The swaps tried so far; this call's are appended.

    Returns
    -------
    tuple or None
        FMU parameters and replays of the model after the swap (its joint refit when that
        judged better).
    """
    trials = rivals(rounds, accepted, {r.removed for r in records if r.kept})
    if not trials:
        return None
    library = selector.library
    others = [
        {k: v for k, v in base.items() if k not in library[accepted[j].name].sets}
        for j, _ in trials
    ]
    fits = selector.tasks(
        "swap_fits",
        [
            FitTask(c.name, o, accepted[j].context, tuple(c.fit.values.values()))
            for (j, c), o in zip(trials, others, strict=True)
        ],
    )
    models = [
        accepted[:j] + [_accepted_as(fit, accepted[j])] + accepted[j + 1 :]
        for (j, _), fit in zip(trials, fits, strict=True)
    ]
    count = len(trials)
    first = selector.tasks(
        "swap_fits",
        [SimulateTask(f.overrides, with_training=True) for f in fits]
        + [selector.refit_task(m) for m in models],
    )
    sequential, refits = first[:count], first[count:]
    joint = selector.tasks(
        "swap_fits", [SimulateTask(r.overrides, with_training=True) for r in refits]
    )
    judging = selector.judging
    held = judging.residuals(replays)
    vector = judging.vector(held)
    basis = selector.basis(base)

    def left(trial: Replays) -> float:
        return float(np.linalg.norm(basis.correction(judging.vector(judging.residuals(trial)))[1]))

    critical = critical_z(selector.settings.acceptance_level, count)
    tried = []
    for k, ((j, rival), fit, model) in enumerate(zip(trials, fits, models, strict=True)):
        overrides, trial = dict(fit.overrides), sequential[k]
        if left(joint[k]) < left(trial):
            overrides, trial = dict(refits[k].overrides), joint[k]
        n_parameters = sum(len(library[a.name].parameters) for a in model)
        candidate = Candidate(
            FitResult(fit.hypothesis, fit.values, overrides, fit.train_cost, fit.replays, ""),
            len(library[rival.name].parameters),
            bic(fit.train_cost, n_parameters, selector.train_seconds),
            replays=trial,
        )
        candidate.size_above_tolerance = selector.size_above_tolerance(
            library[rival.name], tuple(fit.values.values()), others[k]
        )
        judge(candidate, judging, selector.settings, len(library), held, vector, basis, critical)
        tried.append((model, Swap(accepted[j].name, candidate)))
    records.extend(record for _, record in tried)
    passing = [(model, record) for model, record in tried if record.candidate.passes]
    if not passing:
        return None
    model, made = min(passing, key=lambda pair: pair[1].candidate.bic)
    made.kept = True
    accepted[:] = model
    return dict(made.candidate.fit.overrides), made.candidate.replays


def _accepted_as(fit: FitResult, replaced: Accepted) -> Accepted:
    """The rival's fit as an accepted effect in the place (context, round) of ``replaced``."""
    return Accepted([fit.hypothesis], tuple(fit.values.values()), replaced.context, replaced.round)
