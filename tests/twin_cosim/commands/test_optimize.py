"""What ``twin optimize`` prints of a campaign's result."""

from __future__ import annotations

from pathlib import Path

from twin_cosim.commands.optimize import _report
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
