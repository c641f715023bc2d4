"""The records of the selection: ranking helpers and which candidate a round accepted."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.floors.calibration import CalibrationFloor
from twin_cosim.gap.which.replay import FitResult
from twin_cosim.gap.which.rounds import Candidate, Pair, Round, bic, correlation


def _candidate(name: str, cost: float = 1.0) -> Candidate:
    return Candidate(FitResult(name, {}, {}, cost, 0, ""), 1, bic(cost, 1, 5.0))


def _round(candidates: list[Candidate], accepted: list[str], pair: Pair | None = None) -> Round:
    floor = CalibrationFloor(2.0, 1.5, 1.3, {})
    return Round(1, {}, True, 2.0, 1.0, 0.1, floor, [], candidates, accepted, [], pair)


def test_bic_charges_each_parameter_the_log_of_the_independent_samples():
    # 5 s of training at one independent sample per 10 ms: n_eff = 500
    assert bic(1.0, 2, 5.0) - bic(1.0, 1, 5.0) == pytest.approx(np.log(500.0))
    assert bic(0.5, 1, 5.0) < bic(1.0, 1, 5.0)


def test_correlation_of_predicted_changes_ignores_sign_and_constants():
    a = np.sin(np.linspace(0.0, 6.0, 50))
    assert correlation(a, -2.0 * a) == pytest.approx(1.0)
    assert correlation(a, np.ones(50)) == 0.0
    assert correlation(a, a[:10]) == 0.0


def test_a_round_names_its_accepted_single_or_pair():
    single = _candidate("stribeck")
    other = _candidate("backlash_change")
    assert _round([other, single], ["stribeck"]).best is single
    assert _round([other, single], []).best is None
    pair = Pair(
        FitResult("backlash_change+stribeck", {}, {}, 0.5, 0, ""),
        3,
        bic(0.5, 3, 5.0),
        members=("backlash_change", "stribeck"),
        member_values=((8e-6,), (0.2, 0.3)),
    )
    chosen = _round([other, single], ["backlash_change", "stribeck"], pair)
    assert chosen.best is pair
    assert chosen.best.name == "backlash_change+stribeck"
