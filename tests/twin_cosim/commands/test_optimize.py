"""What ``twin optimize`` prints of a campaign's result."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from twin_cosim.commands.optimize import SETTLING_WEIGHT, _report, objective_terms
from twin_cosim.optimize.axis_problem import CampaignSpec
from twin_cosim.optimize.driver import CampaignResult

SPEC = CampaignSpec("reference1", "ce", seed=1)


def result(status: str, fitness: float, metrics: dict | None) -> CampaignResult:
    return CampaignResult(
        method="ce",
        best_params={"Kp_pos": 50.0},
        fitness=fitness,
        status=status,
        metrics=metrics,
        evaluations=20,
        evaluations_reused=0,
        generations=1,
        stop_reason="evaluation budget of 20 exhausted",
        wall_s=0.4,
        reference={"E_pk_um": 13.139},
        out_dir="c",
        details={"settings": {}},
    )


def test_a_valid_best_run_is_its_e_pk(capsys):
    _report(SPEC, result("ok", 2.0663, {"E_pk_um": 2.0663}), Path("c"), False)
    assert capsys.readouterr().out.startswith("CE: best E_pk 2.066 um (reference 13.139 um)")


def test_a_campaign_without_a_valid_run_says_so_without_a_nan(capsys):
    _report(SPEC, result("unstable", 2e6, None), Path("c"), False)
    out = capsys.readouterr().out
    assert "nan" not in out
    assert "no valid run (the best candidate's status: unstable; its score 2e+06 um" in out


def test_a_penalised_best_run_is_said_to_be(capsys):
    _report(SPEC, result("violation", 1e6 + 3.2, {"E_pk_um": 3.2}), Path("c"), False)
    assert "best E_pk 3.200 um, above the IAU cap (penalised)" in capsys.readouterr().out


def test_objective_terms_read_the_aggregate_and_the_settling_weight():
    assert objective_terms("mean") == {"aggregate": "mean"}
    assert objective_terms("settling") == {"settling_weight": SETTLING_WEIGHT}
    assert objective_terms("worst,settling=0.2") == {"aggregate": "worst", "settling_weight": 0.2}
    for bad in ("best", "settling=-1", "settling=x", "mean,worst", "settling,settling=1"):
        with pytest.raises(argparse.ArgumentTypeError):
            objective_terms(bad)


def test_the_result_says_the_settling_time_beside_e_pk(capsys):
    metrics = {"E_pk_um": 2.7, "IAU": 7.9, "settling_ms": 20.7}
    _report(SPEC, result("ok", 3.735, metrics), Path("c"), as_json=False)
    assert "best E_pk 2.700 um, settling 20.7 ms (fitness 3.735 um)" in capsys.readouterr().out
