"""Calibrated and robust campaigns: checkpoint, resume, and the settings they are bound to."""

from __future__ import annotations

import json
import shutil

import pytest
from scenario_texts import scenario_text

from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.store import CampaignError
from twin_cosim.scenario.plant_parameters import PlantParameters, write_plant_parameters

SMALL_CE = "methods: {ce: {population_size: 10, elite_fraction: 0.2}}"
SHORT = scenario_text(optimize=SMALL_CE)


@pytest.fixture()
def files(tmp_path):
    first, second = tmp_path / "a.yaml", tmp_path / "b.yaml"
    first.write_text(SHORT)
    second.write_text(scenario_text("b", acceleration=0.1, optimize=SMALL_CE))
    plant = write_plant_parameters(
        tmp_path / "plant.yaml",
        PlantParameters("drive2mass", {"backlash": 15e-6, "stribeck_friction": 0.1}),
    )
    return str(first), str(second), str(plant)


def robust_spec(files, **changes) -> CampaignSpec:
    first, second, plant = files
    settings = dict(
        plant_parameters=plant, scenarios=[second], tolerance=0.03, samples=2, budget=30, seed=2
    )
    return CampaignSpec(first, "ce", **(settings | changes))


@pytest.mark.parametrize("relative", [False, True])
def test_robust_campaign_resumes_to_the_same_result(files, tmp_path, relative):
    spec = robust_spec(files, relative=relative)
    whole = run_campaign(AxisProblem.resolve(spec), tmp_path / "whole", workers=1, progress=False)
    header = json.loads((tmp_path / "whole" / "campaign.json").read_text())
    assert header["robust"]["plant_parameters"]["backlash"] == 15e-6
    assert len(header["robust"]["samples"]) == 2 and header["robust"]["samples"][0] == {}
    assert "stribeck_friction" in header["robust"]["uncertain_parameters"]
    assert len(whole.metrics["runs"]) == 4
    # A crash inside generation 2: keep the first 15 logged evaluations only.
    cut = tmp_path / "cut"
    shutil.copytree(tmp_path / "whole", cut)
    lines = (cut / "evaluations.jsonl").read_text().splitlines(keepends=True)
    (cut / "evaluations.jsonl").write_text("".join(lines[:15]))
    (cut / "result.json").unlink()
    resumed = run_campaign(AxisProblem.resolve(spec), cut, workers=1, resume=True, progress=False)
    assert resumed.best_params == whole.best_params
    assert resumed.fitness == whole.fitness
    assert resumed.evaluations == whole.evaluations
    assert resumed.evaluations_reused >= 15


def test_resume_refuses_a_changed_plant_file(files, tmp_path):
    run_campaign(
        AxisProblem.resolve(robust_spec(files, budget=10)),
        tmp_path / "c",
        workers=1,
        progress=False,
    )
    write_plant_parameters(files[2], PlantParameters("drive2mass", {"backlash": 16e-6}))
    with pytest.raises(CampaignError, match="plant_parameters"):
        run_campaign(
            AxisProblem.resolve(robust_spec(files, budget=10)),
            tmp_path / "c",
            workers=1,
            resume=True,
        )


def test_samples_need_a_tolerance(files, tmp_path):
    with pytest.raises(ValueError, match="--tolerance"):
        run_campaign(
            AxisProblem.resolve(robust_spec(files, tolerance=0.0)), tmp_path / "d", workers=1
        )


def test_each_case_is_judged_against_its_own_reference_run(files, tmp_path):
    spec = robust_spec(files, budget=10, relative=True)
    result = run_campaign(AxisProblem.resolve(spec), tmp_path / "rel", workers=1, progress=False)
    cases = json.loads((tmp_path / "rel" / "campaign.json").read_text())["cases"]
    labels = ["short/sample0", "short/sample1", "b/sample0", "b/sample1"]
    assert [c["case"] for c in cases] == labels
    first = cases[0]["reference"]["E_pk_um"]
    for case in cases:
        assert case["iau_limit"] == pytest.approx(1.05 * case["reference"]["IAU"])
        assert case["scale"] == pytest.approx(first / case["reference"]["E_pk_um"])
    assert len({c["reference"]["IAU"] for c in cases}) == 4  # every case needs its own limit
    scaled = [
        c["scale"] * run["E_pk_um"] for c, run in zip(cases, result.metrics["runs"], strict=True)
    ]
    assert result.fitness == pytest.approx(max(scaled))


def test_resume_refuses_a_change_of_relative(files, tmp_path):
    run_campaign(
        AxisProblem.resolve(robust_spec(files, budget=10)),
        tmp_path / "r",
        workers=1,
        progress=False,
    )
    with pytest.raises(CampaignError, match="different campaign"):
        run_campaign(
            AxisProblem.resolve(robust_spec(files, budget=10, relative=True)),
            tmp_path / "r",
            workers=1,
            resume=True,
        )
