"""Scenario files load, and every mistake is named with the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin_cosim import paper
from twin_cosim.scenario import ScenarioError, load_scenario, load_tuned_parameters

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
BASE = """
name: t
reference:
  segments:
    - dwell: 0.1
    - move: {to: 0.001, velocity: 0.01, acceleration: 0.1}
"""


@pytest.mark.parametrize("name", ["reference1", "reference2"])
def test_shipped_scenarios_load(name):
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    assert scenario.tuned == paper.FINE_TUNE
    assert scenario.reference.period == 250e-6


def test_reference1_lasts_about_ten_seconds():
    assert 8.0 <= load_scenario(SCENARIOS / "reference1.yaml").reference.duration <= 12.0


def write(tmp_path, text: str) -> Path:
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    return path


def test_scientific_notation_without_dot_is_a_number(tmp_path):
    scenario = load_scenario(write(tmp_path, BASE + "plant:\n  parameters: {backlash: 1e-5}\n"))
    assert scenario.plant_parameters["backlash"] == 1e-5


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("colour: red\n", r"\(top level\): unknown key\(s\) \['colour'\]"),
        (
            "plant:\n  parameters: {backlash: fast}\n",
            "plant.parameters.backlash: expected a number",
        ),
        (
            "plant:\n  parameters: {backlash: .nan}\n",
            "plant.parameters.backlash: expected a finite number",
        ),
        (
            "controller:\n  settings: {current_limt: 5}\n",
            r"controller.settings: unknown key\(s\) \['current_limt'\]",
        ),
        ("controller:\n  settings: {current_limit: -5}\n", "current_limit must be finite and >= 0"),
        ("controller:\n  parameters: {Kp_pos: 1}\n", "missing"),
        ("run:\n  metrics_window: [0.0, 99.0]\n", "run.metrics_window: expected 0 <= t0 < tF"),
    ],
)
def test_mistakes_are_named(tmp_path, extra, message):
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(write(tmp_path, BASE + extra))
    assert "scenario.yaml" in str(info.value)


@pytest.mark.parametrize(
    ("reference", "message"),
    [
        ("reference:\n  segments: []\n", "reference.segments: expected a non-empty list"),
        ("reference:\n  segments:\n    - jump: 1\n", r"reference.segments\[0\]: expected one of"),
        (
            "reference:\n  segments:\n    - move: {to: 1, velocity: -1, acceleration: 1}\n",
            r"reference.segments\[0\].move.velocity: expected a number > 0",
        ),
        (
            "reference:\n  segments:\n    - ramp: {velocity: 0.01, acceleration: 1, duration: 1}\n",
            "ends moving",
        ),
        ("reference:\n  csv: none.csv\n", "cannot read reference CSV"),
        ("name: x\n", "reference: expected a reference section"),
    ],
)
def test_reference_mistakes_are_named(tmp_path, reference, message):
    with pytest.raises(ScenarioError, match=message):
        load_scenario(write(tmp_path, reference))


def test_malformed_yaml(tmp_path):
    with pytest.raises(ScenarioError, match="malformed YAML"):
        load_scenario(write(tmp_path, "reference: [\n"))


def test_params_from_table3_or_file(tmp_path):
    assert load_tuned_parameters("GA") == paper.TABLE3["ga"]
    path = tmp_path / "best.json"
    path.write_text('{"best_params": ' + str(paper.TABLE3["ce"].as_dict()).replace("'", '"') + "}")
    assert load_tuned_parameters(str(path)) == paper.TABLE3["ce"]
    with pytest.raises(ScenarioError, match="neither a set of Table 3"):
        load_tuned_parameters("xx")
