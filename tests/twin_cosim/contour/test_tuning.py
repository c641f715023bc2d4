"""Tuning for contours: the objective scores every axis' parameters; the campaign checkpoints,
resumes to the same result and refuses a different one."""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pytest

from twin_cosim.commands.optimize import _outcome
from twin_cosim.contour.machine_run import contour_metrics
from twin_cosim.contour.tuning import (
    ContourCampaignSpec,
    ContourObjectiveSpec,
    MachineProblem,
    cases_of,
    contour_settings,
    machine_vector,
)
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.early_stop import EvaluationTask
from twin_cosim.optimize.store import CampaignError
from twin_cosim.scenario import ScenarioError, load_machine

MACHINE = """
axes: {X: {}, Y: {}}
optimize:
  target: G
  circles: {radii_mm: [5], feeds_mm_min: [2000, 1000], directions: [ccw]}
"""


@pytest.fixture()
def machine_file(tmp_path):
    path = tmp_path / "xy.yaml"
    path.write_text(textwrap.dedent(MACHINE))
    return path


def test_settings_name_every_axis_parameter_and_refuse_bad_keys(machine_file, tmp_path):
    machine = load_machine(machine_file)
    settings = contour_settings(machine)
    assert settings.config.names[:2] == ("X.Kp_pos", "X.Kp_vel")
    assert len(settings.config.names) == 12 and len(settings.circles) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("axes: {X: {}, Y: {}}\noptimize: {target: E_pk}\n")
    with pytest.raises(ScenarioError, match="bad.yaml: optimize.target"):
        contour_settings(load_machine(bad))


def test_the_objective_scores_the_reference_at_its_own_value_and_caps_iau(machine_file):
    machine = load_machine(machine_file)
    settings = contour_settings(machine)
    probe = ContourObjectiveSpec(machine, settings, cases_of(settings, None)).build()
    references = tuple(probe.reference_of(case) for case in range(len(probe.spec.cases)))
    probe.close()
    objective = ContourObjectiveSpec(machine, settings, probe.spec.cases, references).build()
    try:
        own = objective(machine_vector(machine))
        assert own["status"] == "ok"
        assert own["fitness"] == pytest.approx(references[0]["G"])  # relative: case 0's units
        runs = {run["case"]: run for run in own["metrics"]["runs"]}
        metrics = own["metrics"]  # each figure beside the case it belongs to
        assert metrics["worst_case_G"] == runs[metrics["worst_case"]]["G"]
        assert metrics["G"] == max(run["G"] for run in runs.values())
        assert metrics["G"] == runs[metrics["G_case"]]["G"]
        hungry = machine_vector(machine).copy()
        hungry[1] = hungry[7] = 1.4  # Kp_vel of both axes: more current
        scored = objective(EvaluationTask(hungry))
        assert scored["status"] in ("violation", "ok")
        stopped = objective(EvaluationTask(machine_vector(machine), cutoff_um=1e-3))
        assert stopped["status"] == "stopped" and stopped["fitness"] > 1e-3
        refused = objective(np.zeros(12))
        assert refused["status"] == "failed"
    finally:
        objective.close()


def test_the_record_of_a_run_is_the_run_a_case_is_scored_on(machine_file):
    machine = load_machine(machine_file)
    settings = contour_settings(machine)
    objective = ContourObjectiveSpec(machine, settings, cases_of(settings, None)).build()
    try:
        own = objective.record(None, 1)
        assert contour_metrics(own)["contour_error_max_um"] == objective.reference_of(1)["contour"]
        stiffer = machine_vector(machine).copy()
        stiffer[0] = stiffer[6] = 120.0  # Kp_pos of both axes
        tuned = objective.record(stiffer, 1)
        assert contour_metrics(tuned)["contour_error_max_um"] != pytest.approx(
            contour_metrics(own)["contour_error_max_um"]
        )
    finally:
        objective.close()


def run_contour_campaign(spec, out, **options):
    return run_campaign(MachineProblem.load(spec), out, **options)


def test_a_campaign_resumes_to_the_same_result_and_refuses_another(machine_file, tmp_path):
    spec = ContourCampaignSpec(str(machine_file), "ce", seed=1, budget=8)
    first = run_contour_campaign(spec, tmp_path / "a", workers=1, progress=False)
    assert set(first.best_params["axes"]) == {"X", "Y"}
    assert first.evaluations == 8 and first.details["reference_fitness"] > 0
    said = _outcome(first)  # relative: a ratio, each figure beside its own case
    ratio = first.fitness / first.details["reference_fitness"]
    assert f"worst case {first.metrics['worst_case']} at {ratio:.3f} of the reference" in said
    assert f"largest G {first.metrics['G']:.3f} um on {first.metrics['G_case']}" in said
    log = (tmp_path / "a" / "evaluations.jsonl").read_text().splitlines()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "campaign.json").write_text((tmp_path / "a" / "campaign.json").read_text())
    (tmp_path / "b" / "evaluations.jsonl").write_text("\n".join(log[:3]) + "\n")
    again = run_contour_campaign(spec, tmp_path / "b", workers=1, resume=True, progress=False)
    assert again.best_params == first.best_params
    assert again.evaluations_reused == 3
    other = ContourCampaignSpec(str(machine_file), "ce", seed=2, budget=8)
    with pytest.raises(CampaignError, match="different campaign"):
        run_contour_campaign(other, tmp_path / "b", workers=1, resume=True, progress=False)
    result = json.loads((tmp_path / "a" / "result.json").read_text())
    assert result["best_params"] == first.best_params


def test_a_campaign_may_start_from_other_sets_and_a_resume_keeps_them(machine_file, tmp_path):
    spec = ContourCampaignSpec(str(machine_file), "ce", seed=0, budget=2, start="ga")
    run_contour_campaign(spec, tmp_path / "c", workers=1, progress=False)
    header = json.loads((tmp_path / "c" / "campaign.json").read_text())
    assert header["spec"]["start"] == "ga"
    assert header["reference_params"]["X"]["Kp_pos"] == pytest.approx(66.6667)  # still Fine-Tune
    other = ContourCampaignSpec(str(machine_file), "ce", seed=0, budget=2, start="sa")
    with pytest.raises(CampaignError, match="different campaign"):
        run_contour_campaign(other, tmp_path / "c", workers=1, resume=True, progress=False)
