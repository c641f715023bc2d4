"""Pairs of hypotheses that only pass together.

Effects that act in the same place (backlash beside Stribeck friction, a Coulomb change beside a
smaller backlash) can each make the held-out fit worse alone: each fit bends to explain the
other's part. When no single hypothesis passes a round, the ``pair_candidates`` leading ones by
training BIC are screened in pairs: the second fitted on top of the first (from its own fit of
the round), replayed on the held-out runs and judged as one candidate, with the Bonferroni
count of the round raised by the pairs tried and the fair share doubled; and each member must
earn its place in the pair: the pair against the other member's fit alone passes the evidence
and fair-share tests (:attr:`~twin_cosim.gap.rounds.Pair.within`). The best passing pair by BIC
is accepted, both effects at once.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.calibration import CalibrationBasis
from twin_cosim.gap.floors.evidence import critical_z, excess_share, fair_share, improvement_z
from twin_cosim.gap.which.acceptance import judge
from twin_cosim.gap.which.replay import FitResult, FitTask, SimulateTask
from twin_cosim.gap.which.rounds import Marginal, Pair, Round, bic

if TYPE_CHECKING:
    from twin_cosim.gap.which.selector_view import SelectorView


def screen_pairs(
    selector: SelectorView,
    current: Round,
    base: dict[str, float],
    held: Residuals,
    vector: np.ndarray,
    basis: CalibrationBasis,
    singles: int,
) -> list[Pair]:
    """Pairs of the round's leading hypotheses by training BIC, the second fitted on top of
    the first, judged as one candidate and each member against the other alone (module
    docstring); best training BIC first.

    Parameters
    ----------
    selector
        The selection (pool, held-out runs, settings, hypothesis library).
    current
        The round, its candidates fitted and judged (best training BIC first).
    base
        FMU parameters of the accepted effects.
    held, vector
        The held-out residual at the start of the round, and its normalised vector.
    basis
        Calibration directions around ``base``.
    singles
        Hypotheses judged alone in the round (for the Bonferroni count).
    """
    leaders = [c for c in current.candidates if math.isfinite(c.bic) and c.fit.values]
    couples = list(itertools.combinations(leaders[: selector.settings.pair_candidates], 2))
    if not couples:
        return []
    fits = selector.tasks(
        "pair_fits",
        [
            FitTask(b.name, dict(a.fit.overrides), current.context, tuple(b.fit.values.values()))
            for a, b in couples
        ],
    )
    replays = selector.tasks("pair_replays", [SimulateTask(f.overrides) for f in fits])
    critical = critical_z(selector.settings.acceptance_level, singles + len(couples))
    least_share = fair_share(len(selector.library))
    duration = selector.judging.duration_s
    pairs = []
    for (a, b), fit, replay in zip(couples, fits, replays, strict=True):
        values = (tuple(a.fit.values.values()), tuple(fit.values.values()))
        n_parameters = a.n_parameters + b.n_parameters
        pair = Pair(
            FitResult(
                f"{a.name}+{b.name}",
                {f"{a.name}.{k}": v for k, v in a.fit.values.items()}
                | {f"{b.name}.{k}": v for k, v in fit.values.items()},
                fit.overrides,
                fit.train_cost,
                fit.replays,
                fit.message,
            ),
            n_parameters,
            bic(fit.train_cost, n_parameters, selector.train_seconds),
            replays=replay,
            members=(a.name, b.name),
            member_values=values,
        )
        pair.size_above_tolerance = selector.size_above_tolerance(
            selector.library[a.name], values[0], base
        ) and selector.size_above_tolerance(selector.library[b.name], values[1], a.fit.overrides)
        judge(
            pair,
            selector.judging,
            selector.settings,
            len(selector.library),
            held,
            vector,
            basis,
            critical,
            shares=2,
        )
        with_both = basis.correction(selector.judging.vector(selector.judging.residuals(replay)))[1]
        for member, other in ((a, b), (b, a)):
            alone = selector.judging.vector(selector.judging.residuals(other.replays))
            without = basis.correction(alone)[1]
            z = improvement_z(without, with_both, duration)
            share = excess_share(without, with_both)
            pair.within.append(
                Marginal(
                    member.name,
                    z,
                    share,
                    float(np.linalg.norm(without)),
                    float(np.linalg.norm(with_both)),
                )
            )
            pair.passes = pair.passes and z >= critical and share >= least_share
        pairs.append(pair)
    return sorted(pairs, key=lambda p: p.bic)
