"""Scenario files load, and every mistake is named with the file and the key."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from fmu_build.build import CACHE_ENV
from twin_cosim.controller_set import FINE_TUNE, TABLE3
from twin_cosim.environment import DATA_ENV
from twin_cosim.scenario import (
    ScenarioError,
    find_scenario,
    load_controller_set,
    load_scenario,
    plant_mismatch,
)

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
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
    assert scenario.tuned == FINE_TUNE
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
        ("controller:\n  parameters: xx\n", r"controller.parameters: expected the six"),
        ("plant:\n  model: nope\n", "plant.model: expected one of the project's models"),
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
    assert load_controller_set("GA").tuned == TABLE3["ga"]
    path = tmp_path / "best.json"
    path.write_text('{"best_params": ' + str(TABLE3["ce"].as_dict()).replace("'", '"') + "}")
    assert load_controller_set(str(path)).tuned == TABLE3["ce"]
    with pytest.raises(ScenarioError, match="neither a set of Table 3"):
        load_controller_set("xx")


def test_shipped_scenarios_are_found_by_name():
    assert find_scenario("reference1") == SCENARIOS / "reference1.yaml"
    assert load_scenario("reference2").name == "reference2"
    with pytest.raises(ScenarioError, match=r"nope: neither a scenario file nor a shipped"):
        load_scenario("nope")


def test_fine_tune_is_taken_by_name_from_the_paper(tmp_path):
    scenario = load_scenario(write(tmp_path, BASE + "controller:\n  parameters: ga\n"))
    assert scenario.tuned == TABLE3["ga"]


def test_controller_plant_facts_follow_the_scenario_plant(tmp_path):
    """The drive's travel, inertia, K_t and friction follow the plant parameters (no copies)."""
    scenario = load_scenario(
        write(
            tmp_path,
            BASE + "plant:\n  parameters: {gear_ratio: 2.0, motor_inertia: 1.0e-3, "
            "torque_constant: 0.5, coulomb_friction: 0.3}\n",
        )
    )
    settings = scenario.settings
    assert settings.travel_per_rad == pytest.approx(0.010 / (2 * math.pi) / 2.0)
    assert settings.inertia == pytest.approx(1.0e-3 + 4.2e-4)
    assert (settings.torque_constant, settings.friction_torque) == (0.5, 0.3)
    chosen = load_scenario(
        write(tmp_path, BASE + "controller:\n  settings: {friction_torque: 0.0}\n")
    )
    assert chosen.settings.friction_torque == 0.0


def test_measured_data_is_looked_up_in_the_data_folder(tmp_path, monkeypatch):
    scenario_file = write(
        tmp_path,
        "reference:\n  measured: far/away/run.csv\n"
        "  data_source: The run comes from the test's own axis.\n",
    )
    monkeypatch.delenv(DATA_ENV, raising=False)
    with pytest.raises(ScenarioError) as info:
        load_scenario(scenario_file)
    message = str(info.value)
    assert "reference.measured: run.csv not found" in message
    assert "The run comes from the test's own axis." in message
    assert f"--data DIR or the environment variable {DATA_ENV}=DIR" in message
    data = tmp_path / "data"
    data.mkdir()
    t = np.arange(400) * 1e-3
    x = 1e-3 * (1 - np.cos(np.pi * t / t[-1]))
    pd.DataFrame({"t": t, "x_ref": x, "x": x, "current": 0 * t}).to_csv(
        data / "run.csv", index=False
    )
    monkeypatch.setenv(DATA_ENV, str(data))
    assert load_scenario(scenario_file).measured == data / "run.csv"


def test_a_plant_of_another_model_is_a_mismatch(fmu_path, tmp_path):
    from fmu_build.build import build_fmu

    scenario = load_scenario(SCENARIOS / "reference1.yaml")
    assert plant_mismatch(scenario, fmu_path) is None
    warning = plant_mismatch(scenario, build_fmu("emps"))
    assert "made for the plant model 'drive2mass'" in warning
    assert "is model 'emps'" in warning


def test_loading_a_scenario_never_compiles(tmp_path, monkeypatch):
    """A scenario of a model whose FMU is not built loads without building it; the FMU is built
    when a run first asks for it."""
    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    scenario = load_scenario("reference1")
    assert scenario.fmu is None and scenario.model == "drive2mass"
    assert not cache.exists() or not any(cache.rglob("*.fmu"))
    assert scenario.plant_fmu().is_file()
    assert scenario.plant_fmu().is_relative_to(cache)
