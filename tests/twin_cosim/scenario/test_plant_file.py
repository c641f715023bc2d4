"""Plant parameter files: built from a real diagnosis, read back exactly, checked, applied."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest
import yaml
from scenario_texts import scenario_text

from twin_cosim import cli
from twin_cosim.gap import settings as diagnosis_settings
from twin_cosim.gap.report.calibrated_plant import calibrated_scenario, from_diagnosis
from twin_cosim.gap.synth import parse_effect, synthesize
from twin_cosim.scenario import ScenarioError, load_scenario, with_plant_parameters
from twin_cosim.scenario.plant_file import (
    PlantParameters,
    PlantParametersError,
    read_plant_parameters,
    write_plant_parameters,
)

NOMINAL_COULOMB = 0.625  # N.m, Table 1 (models/drive2mass/variables.yaml)
# A short excitation: two back-and-forth moves at 20 mm/s with dwells (about 6 s).
SHORT_EXCITATION = scenario_text(
    "short-excitation", speed=0.02, acceleration=0.2, move=1.0, stop=0.2, dwell=0.3, repeat=2
)
HIDDEN = ("coulomb_change:delta_coulomb=0.2", "plant:noise_amplitude_1=3e-7,noise_frequency_1=37")


@pytest.fixture(scope="module")
def excitation(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("excitation") / "short.yaml"
    path.write_text(SHORT_EXCITATION)
    return path


@pytest.fixture(scope="module")
def diagnosis_dir(excitation, tmp_path_factory) -> Path:
    """``twin diagnose --out DIR`` on a run with a known answer (two hypotheses, to stay fast)."""
    scenario = load_scenario(excitation)
    synthesis = synthesize(scenario, [parse_effect(e) for e in HIDDEN], seed=1)
    run = tmp_path_factory.mktemp("run") / "run.csv"
    synthesis.run.frame().to_csv(run, index=False)
    out = tmp_path_factory.mktemp("diagnosis")

    def two_hypotheses(*args, **kwargs):  # the whole library would take minutes
        settings = original(*args, **kwargs)
        return dataclasses.replace(settings, hypotheses=("coulomb_change", "backlash_change"))

    original = diagnosis_settings.settings_from
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(diagnosis_settings, "settings_from", two_hypotheses)
        argv = ["diagnose", str(excitation), "--measured", str(run), "--max-effects", "1"]
        assert cli.main([*argv, "--workers", "1", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def diagnosis_summary(diagnosis_dir) -> dict:
    """The JSON summary ``twin diagnose`` wrote."""
    return json.loads((diagnosis_dir / "diagnosis.json").read_text())


def test_plant_yaml_of_a_real_diagnosis_holds_the_hidden_answer(diagnosis_summary, tmp_path):
    assert diagnosis_summary["accepted"] == ["coulomb_change"]
    plant = from_diagnosis(diagnosis_summary, "drive2mass", {"command": "twin diagnose ..."})
    assert plant.parameters["coulomb_friction"] == pytest.approx(NOMINAL_COULOMB + 0.2, rel=0.05)
    assert "coulomb_change" in plant.provenance["coulomb_friction"]["source"]
    assert plant.provenance["coulomb_friction"]["holdout_reduction"] >= 0.25
    assert plant.parameters["noise_frequency_1"] == pytest.approx(37.0, rel=0.01)
    assert plant.parameters["noise_amplitude_1"] == pytest.approx(3e-7, rel=0.2)
    assert "noise" in plant.provenance["noise_amplitude_1"]["source"]
    assert plant.created_by["measured"] == diagnosis_summary["measured"]
    path = write_plant_parameters(tmp_path / "plant.yaml", plant)
    back = read_plant_parameters(path, "drive2mass")
    assert back.parameters == plant.parameters  # floats round-trip exactly
    assert back.provenance == plant.provenance


def test_diagnose_writes_plant_and_calibrated_yaml(diagnosis_dir, diagnosis_summary):
    written = read_plant_parameters(diagnosis_dir / "plant.yaml", "drive2mass")
    assert written.parameters == from_diagnosis(diagnosis_summary, "drive2mass").parameters
    assert written.created_by["command"].startswith("twin diagnose ")
    calibrated = load_scenario(diagnosis_dir / "calibrated.yaml")
    for name, value in written.parameters.items():
        assert calibrated.plant_parameters[name] == value


def test_calibrated_scenario_folds_the_parameters_in(diagnosis_summary, excitation, tmp_path):
    plant = from_diagnosis(diagnosis_summary, "drive2mass")
    out = tmp_path / "deeper" / "calibrated.yaml"
    out.parent.mkdir()
    calibrated = load_scenario(calibrated_scenario(excitation, plant, out))
    for name, value in plant.parameters.items():
        assert calibrated.plant_parameters[name] == value
    assert calibrated.reference.duration == load_scenario(excitation).reference.duration


def write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ({"model": "drive2mass", "parameters": {"no_such": 1.0}}, "parameters.no_such: not a"),
        ({"model": "drive2mass", "parameters": {"backlash": math.nan}}, "parameters.backlash: "),
        ({"model": "drive2mass", "parameters": {"motor_inertia": -1.0}}, "outside the model's"),
        ({"model": "drive2mass", "parameters": {"dead_time_steps": 1.5}}, "expected an integer"),
        ({"model": "drive2mass", "parameters": {"backlash": "x"}}, "expected a number in m"),
        ({"model": "drive2mass", "parameters": {}, "extra": 1}, "unknown key(s) ['extra']"),
        ({"model": "nope", "parameters": {}}, "unknown plant model 'nope'"),
        ({"model": "emps", "parameters": {}}, "the scenario's plant is 'drive2mass'"),
        ({"parameters": {}}, "model: expected a plant model name"),
    ],
)
def test_bad_files_are_named_errors(tmp_path, content, message):
    path = write(tmp_path / "bad_plant.yaml", content)
    with pytest.raises(PlantParametersError) as error:
        read_plant_parameters(path, "drive2mass")
    assert str(error.value).startswith(f"{path}:")
    assert message in str(error.value)


def test_scenario_key_and_command_line_file(excitation, tmp_path):
    write_plant_parameters(
        tmp_path / "plant.yaml", PlantParameters("drive2mass", {"backlash": 20e-6})
    )
    text = excitation.read_text().replace(
        "name: short-excitation", "name: s\nplant:\n  parameters_file: plant.yaml"
    )
    (tmp_path / "s.yaml").write_text(text)
    scenario = load_scenario(tmp_path / "s.yaml")
    assert scenario.plant_parameters["backlash"] == 20e-6
    assert scenario.plant_parameters_file == tmp_path / "plant.yaml"
    other = write_plant_parameters(
        tmp_path / "other.yaml", PlantParameters("drive2mass", {"backlash": 30e-6})
    )
    assert with_plant_parameters(scenario, other).plant_parameters["backlash"] == 30e-6
    (tmp_path / "twice.yaml").write_text(
        text.replace(
            "parameters_file: plant.yaml",
            "parameters_file: plant.yaml\n  parameters: {backlash: 1e-6}",
        )
    )
    with pytest.raises(ScenarioError, match=r"twice.yaml: plant.parameters: .*\['backlash'\]"):
        load_scenario(tmp_path / "twice.yaml")
    write(tmp_path / "plant.yaml", {"model": "emps", "parameters": {}})
    with pytest.raises(ScenarioError, match=r"s.yaml: plant.parameters_file: .*'drive2mass'"):
        load_scenario(tmp_path / "s.yaml")


def test_the_calibration_correction_of_the_last_round_is_applied():
    summary = {
        "steps": [
            {
                "plant_parameters": {"coulomb_friction": 0.5},
                "fitted": "coulomb_change",
                "effect": "coulomb_change",
            }
        ],
        "rounds": [
            {"accepted": ["coulomb_change"], "calibration": {"coefficients": {"backlash": 1.0}}},
            {
                "accepted": [],
                "calibration": {
                    "coefficients": {"motor_inertia": 1.0, "coulomb_friction": -0.5, "backlash": 0}
                },
            },
        ],
        "thresholds": {"calibration_tolerance": 0.03},
    }
    plant = from_diagnosis(summary, "drive2mass", nominal={"motor_inertia": 2e-4})
    assert plant.parameters["motor_inertia"] == pytest.approx(2e-4 * 1.03)  # the scenario's value
    assert plant.parameters["coulomb_friction"] == pytest.approx(0.5 * 0.985)  # the effect's value
    assert "backlash" not in plant.parameters  # a zero coefficient changes nothing
    assert plant.provenance["motor_inertia"]["relative_change"] == pytest.approx(0.03)
    assert "calibration correction" in plant.provenance["motor_inertia"]["source"]
    # A last round that accepted an effect saw the residual before it: no correction then.
    summary["rounds"][-1]["accepted"] = ["backlash_change"]
    plant = from_diagnosis(summary, "drive2mass")
    assert plant.parameters == {"coulomb_friction": 0.5}


def test_a_hand_edited_plant_file_reads_as_a_scenario_does(tmp_path):
    """One loader: 2e-5 (no dot) is a number in plant.yaml as in a scenario, and a malformed
    file fails with the scenarios' error, naming the file."""
    path = tmp_path / "plant.yaml"
    path.write_text("model: drive2mass\nparameters:\n  backlash: 2e-5\n  stribeck_speed: 1e0\n")
    assert read_plant_parameters(path).parameters == {"backlash": 2e-5, "stribeck_speed": 1.0}
    path.write_text("model: drive2mass\nparameters: {backlash: [\n")
    with pytest.raises(ScenarioError, match=rf"^{path}: malformed YAML"):
        read_plant_parameters(path)
