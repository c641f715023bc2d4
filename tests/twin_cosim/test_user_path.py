"""What a new user trips on (issue 18, item 5): each names the file, key or option it is about."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from scenario_texts import scenario_text

from fmu_build.build import build_fmu
from twin_cosim.cli import main
from twin_cosim.commands.gap import EFFECTS_HELP
from twin_cosim.optimize.comparison import load_comparison
from twin_cosim.plant_model import model_names, plant_model
from twin_cosim.scenario import ScenarioError, load_scenario
from twin_cosim.scenario.loader import packaged_scenarios_dir

ROOT = Path(__file__).resolve().parents[2]
SHORT = scenario_text(move=0.2, back=False)


def test_a_campaign_file_accepts_shipped_scenario_names(tmp_path):
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text("scenario: reference1\nvalidation: reference2\nholdout: [diagnosis]\n")
    comparison = load_comparison(campaign)
    shipped = packaged_scenarios_dir()
    assert comparison.scenario == shipped / "reference1.yaml"
    assert comparison.validation == shipped / "reference2.yaml"
    assert comparison.holdout == [shipped / "diagnosis.yaml"]


def test_compare_takes_a_budget(tmp_path):
    (tmp_path / "short.yaml").write_text(SHORT)
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text("scenario: short.yaml\nmethods: [ce, ga]\nbudgets: {ce: 400}\n")
    out = tmp_path / "out"
    args = ["compare", str(campaign), "--budget", "12", "--workers", "1", "--no-plots"]
    assert main([*args, "--quiet", "--out", str(out)]) == 0
    for method in ("ce", "ga"):
        log = (out / method / "evaluations.jsonl").read_text().splitlines()
        assert len(log) <= 12, method


def test_synth_help_lists_each_models_effects_and_their_parameters():
    for model in model_names():
        line = re.search(rf"^  {model}: (.*?)(?=^  \S)", EFFECTS_HELP, re.S | re.M).group(1)
        listed = re.findall(r"(\w+) \(([\w, ]+)\)", " ".join(line.split()))
        card = [
            (h.name, ", ".join(p.name for p in h.parameters)) for h in plant_model(model).hypotheses
        ]
        assert listed == card, model


def test_an_unknown_effect_lists_only_the_models_effects(tmp_path, capsys):
    status = main(
        [
            "synth",
            "reference1",
            "--effect",
            "viscous_change:delta_viscous=1",
            "--out",
            str(tmp_path / "run.csv"),
        ]
    )
    assert status == 2
    err = capsys.readouterr().err
    assert "'viscous_change' is not an effect of plant model 'drive2mass'" in err
    assert "backlash_change" in err and "offset_change" not in err  # emps' effects stay out


@pytest.mark.parametrize(
    ("parameters", "message"),
    [
        (
            "{backlash: 12.2}",
            r"plant\.parameters\.backlash: 12\.2 m outside the model's range \[0, 0\.01\]",
        ),
        (
            "{coulomb_friction: 625}",
            r"plant\.parameters\.coulomb_friction = 625: the friction torque",
        ),
    ],
    ids=["backlash-in-um", "coulomb-in-mN.m"],
)
def test_a_plant_parameter_in_the_wrong_unit_names_its_key(tmp_path, parameters, message):
    text = (packaged_scenarios_dir() / "reference1.yaml").read_text()
    path = tmp_path / "wrong.yaml"
    path.write_text(text.replace("parameters: {}", f"parameters: {parameters}", 1))
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(path)
    assert str(path) in str(info.value)


def test_the_plant_mismatch_warning_is_printed_once(tmp_path, capsys):
    emps = build_fmu("emps")
    args = ["simulate", "reference1", "--plant", str(emps), "--no-plots", "--out", str(tmp_path)]
    main(args)
    assert capsys.readouterr().err.count("chosen for another plant") == 1


def test_the_machine_synth_writes_is_accepted_by_simulate(tmp_path, capsys):
    run = tmp_path / "run.csv"
    effect = "stribeck:stribeck_friction=0.2,stribeck_speed=0.5"
    assert main(["synth", "reference1", "--effect", effect, "--out", str(run)]) == 0
    machine = tmp_path / "run.csv.machine.yaml"
    assert machine.is_file()
    judged = {}
    for given in (machine, tmp_path / "run.csv.truth.json", run):
        out = tmp_path / given.name.replace(".", "_")
        assert (
            main(
                ["simulate", "reference1", "--machine", str(given), "--no-plots", "--out", str(out)]
            )
            == 0
        )
        summary = json.loads((out / "summary.json").read_text())["machine"]
        judged[given.name] = {k: v for k, v in summary.items() if k != "source"}
    assert judged["run.csv.truth.json"] == judged["run.csv.machine.yaml"]
    assert judged["run.csv.truth.json"]["kind"] == "virtual machine"
