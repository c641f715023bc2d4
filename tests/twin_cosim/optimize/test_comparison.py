"""Comparison files with a calibrated plant, a robust objective and held-out scenarios."""

from __future__ import annotations

import json

import pytest
import yaml
from scenario_texts import scenario_text

from twin_cosim.optimize.comparison import load_comparison, run_comparison
from twin_cosim.scenario import ScenarioError

SHORT = scenario_text()


@pytest.fixture()
def folder(tmp_path):
    (tmp_path / "a.yaml").write_text(SHORT)
    (tmp_path / "b.yaml").write_text(scenario_text("held"))
    (tmp_path / "plant.yaml").write_text(
        yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": 18e-6}})
    )
    return tmp_path


def test_robust_comparison_reports_held_out_scenarios(folder):
    (folder / "c.yaml").write_text(
        "scenario: a.yaml\nmethods: [cmaes]\nbudgets: {cmaes: 8}\nplant_parameters: plant.yaml\n"
        "robust: {scenarios: [b.yaml], tolerance: 0.03, samples: 2, objective: mean}\n"
        "holdout: [b.yaml, fast.yaml]\n"
    )
    (folder / "fast.yaml").write_text(scenario_text("fast", acceleration=0.2))
    comparison = load_comparison(folder / "c.yaml")
    assert comparison.robust["scenarios"] == [str(folder / "b.yaml")]
    assert comparison.robust["aggregate"] == "mean"
    text = run_comparison(comparison, folder / "out", workers=1, progress=False)
    assert "## Held out: held" in text
    beyond = json.loads((folder / "out" / "tables.json").read_text())[
        "holdout_beyond_tuning_motion"
    ]
    assert beyond["held"] == []  # the same motion as the tuning trajectories
    assert any(line.startswith("reversal while moving at 0.2") for line in beyond["fast"])
    assert "Beyond the motion of the tuning trajectories (by more than 20%): " in text
    campaign = json.loads((folder / "out" / "cmaes" / "campaign.json").read_text())
    assert campaign["robust"]["plant_parameters"] == {"backlash": 18e-6}
    assert len(campaign["robust"]["samples"]) == 2
    assert (folder / "out" / "errors_holdout_held.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("robust: {samples: 0}", "robust.samples: expected an integer >= 1"),
        ("robust: {unknown: 1}", "robust: expected a mapping with keys"),
        ("robust: {objective: best}", "robust.objective: expected one of"),
        ("holdout: b.yaml", "holdout: expected a list"),
    ],
)
def test_bad_robust_settings_are_named(folder, line, message):
    (folder / "bad.yaml").write_text(f"scenario: a.yaml\n{line}\n")
    with pytest.raises(ScenarioError, match="bad.yaml: " + message.replace("(", r"\(")):
        load_comparison(folder / "bad.yaml")
