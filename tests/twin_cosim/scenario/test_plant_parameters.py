"""Plant parameter files: built from a real diagnosis, read back exactly, checked, applied."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scenario_texts import scenario_text

from twin_cosim import cli
from twin_cosim.cosim import run_scenario
from twin_cosim.gap import diagnosis as diagnosis_module
from twin_cosim.gap import settings as diagnosis_settings
from twin_cosim.gap.data.residuals import sim_at
from twin_cosim.gap.synth import parse_effect, synthesize
from twin_cosim.metrics import indices
from twin_cosim.plant import Plant
from twin_cosim.scenario import ScenarioError, load_scenario, with_plant_parameters
from twin_cosim.scenario.plant_parameters import (
    PlantParameters,
    PlantParametersError,
    calibrated_scenario,
    read_plant_parameters,
    write_plant_parameters,
)

NOMINAL_COULOMB = 0.625  # N.m, Table 1 (models/drive2mass/variables.yaml)
# A short excitation: two back-and-forth moves at 20 mm/s with dwells (about 6 s).
SHORT_EXCITATION = scenario_text(
    "short-excitation", speed=0.02, acceleration=0.2, move=1.0, stop=0.2, dwell=0.3, repeat=2
)
ERROR = {"position_peak_m": 1e-7, "position_rms_m": 2e-8, "current_rms_A": 5e-3}  # model_error
HIDDEN = ("coulomb_change:delta_coulomb=0.2", "plant:noise_amplitude_1=3e-7,noise_frequency_1=37")


@pytest.fixture(scope="module")
def excitation(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("excitation") / "short.yaml"
    path.write_text(SHORT_EXCITATION)
    return path


@pytest.fixture(scope="module")
def diagnosed(excitation, tmp_path_factory) -> tuple[Path, diagnosis_module.Diagnosis]:
    """``twin diagnose --out DIR`` on a run with a known answer (two hypotheses, to stay fast):
    the folder and the diagnosis it wrote."""
    scenario = load_scenario(excitation)
    synthesis = synthesize(scenario, [parse_effect(e) for e in HIDDEN], seed=1)
    run = tmp_path_factory.mktemp("run") / "run.csv"
    synthesis.run.frame().to_csv(run, index=False)
    out = tmp_path_factory.mktemp("diagnosis")

    def two_hypotheses(*args, **kwargs):  # the whole library would take minutes
        settings = original(*args, **kwargs)
        return dataclasses.replace(settings, hypotheses=("coulomb_change", "backlash_change"))

    made = []

    def kept(*args, **kwargs):  # the diagnosis the command wrote its files from
        made.append(diagnose(*args, **kwargs))
        return made[-1]

    original, diagnose = diagnosis_settings.settings_from, diagnosis_module.diagnose
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(diagnosis_settings, "settings_from", two_hypotheses)
        patch.setattr(diagnosis_module, "diagnose", kept)
        argv = ["diagnose", str(excitation), "--measured", str(run), "--max-effects", "1"]
        assert cli.main([*argv, "--workers", "1", "--out", str(out)]) == 0
    return out, made[0]


@pytest.fixture(scope="module")
def diagnosis_dir(diagnosed) -> Path:
    """The folder ``twin diagnose`` wrote."""
    return diagnosed[0]


@pytest.fixture(scope="module")
def diagnosis_summary(diagnosis_dir) -> dict:
    """The JSON summary ``twin diagnose`` wrote."""
    return json.loads((diagnosis_dir / "diagnosis.json").read_text())


def test_plant_yaml_of_a_real_diagnosis_holds_the_hidden_answer(
    diagnosed, diagnosis_summary, tmp_path
):
    assert diagnosis_summary["accepted"] == ["coulomb_change"]
    plant = diagnosed[1].calibrated_plant
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


def test_plant_yaml_says_what_the_diagnosis_leaves_uncertain(diagnosed, tmp_path):
    """Intervals of the accepted effect's and the calibrated parameters, each holding its
    value; the hidden Coulomb level inside its interval; read back exactly."""
    plant = diagnosed[1].calibrated_plant
    low, high = plant.intervals["coulomb_friction"]
    assert low < NOMINAL_COULOMB + 0.2 < high
    assert high - low < 0.1 * (NOMINAL_COULOMB + 0.2)  # the data pin it down
    for name in ("motor_inertia", "torque_constant", "backlash"):
        low, high = plant.intervals[name]
        value = plant.parameters.get(name, low)
        assert low <= value <= high
        assert 0.0 < (high - low) / value < 4 * 0.03  # within the prior's +/- 2 tolerances
    path = write_plant_parameters(tmp_path / "plant.yaml", plant)
    assert read_plant_parameters(path).intervals == plant.intervals


def test_plant_yaml_says_what_the_twin_still_misses_and_it_bounds_the_held_out_figures(
    diagnosed, excitation
):
    """The effect found, what the calibrated twin misses on the held-out half is the run's
    white noise (20 nm, 5 mA); replayed with plant.yaml (as ``--plant-parameters`` applies
    it), the twin's E_pk, ITAE and IAU on that half lie within the margins it sets of the
    machine's; read back exactly."""
    diagnosis_dir, diagnosis = diagnosed
    error = diagnosis.calibrated_plant.model_error
    assert 15e-9 < error.position_rms_m < 30e-9
    assert 3 * error.position_rms_m < error.position_peak_m < 6 * error.position_rms_m
    assert 4e-3 < error.current_rms_A < 6e-3
    assert read_plant_parameters(diagnosis_dir / "plant.yaml").model_error == error
    scenario = with_plant_parameters(load_scenario(excitation), diagnosis_dir / "plant.yaml")
    with Plant(scenario.plant_fmu()) as plant:
        record = run_scenario(plant, scenario, scenario.tuned)
    held = diagnosis.context.judged[0]
    machine = indices(held.t, held.x_ref - held.x, held.current)
    x_twin, i_twin = (sim_at(record, column, held.t) for column in ("x", "current"))
    twin = indices(held.t, held.x_ref - x_twin, i_twin)
    margins = error.margins(held.t.size * float(np.median(np.diff(held.t))))  # N samples
    for name in ("E_pk_um", "ITAE", "IAU"):
        assert abs(getattr(machine, name) - getattr(twin, name)) <= margins[name]
    assert margins["E_pk_um"] < 0.01 * machine.E_pk_um  # a twin that misses only noise


def test_diagnose_writes_plant_and_calibrated_yaml(diagnosed):
    diagnosis_dir, diagnosis = diagnosed
    written = read_plant_parameters(diagnosis_dir / "plant.yaml", "drive2mass")
    assert written.parameters == diagnosis.calibrated_plant.parameters
    assert written.created_by["command"].startswith("twin diagnose ")
    calibrated = load_scenario(diagnosis_dir / "calibrated.yaml")
    for name, value in written.parameters.items():
        assert calibrated.plant_parameters[name] == value


def test_calibrated_yaml_replays_the_twin_that_plant_yaml_makes(diagnosis_dir, excitation):
    """calibrated.yaml and the scenario with ``--plant-parameters plant.yaml``: the same
    drive settings (the drive's as commissioned, not the calibrated plant's: here a Coulomb
    level 0.2 N.m above the nominal), the same record."""
    folded = load_scenario(diagnosis_dir / "calibrated.yaml")
    applied = with_plant_parameters(load_scenario(excitation), diagnosis_dir / "plant.yaml")
    assert folded.settings == applied.settings == load_scenario(excitation).settings
    records = []
    for scenario in (folded, applied):
        with Plant(scenario.plant_fmu()) as plant:
            records.append(run_scenario(plant, scenario, scenario.tuned))
    assert np.array_equal(records[0]["x"], records[1]["x"])
    assert np.array_equal(records[0]["current"], records[1]["current"])


def test_calibrated_scenario_folds_the_parameters_in(diagnosed, excitation, tmp_path):
    plant = diagnosed[1].calibrated_plant
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
        (
            {
                "model": "drive2mass",
                "parameters": {"backlash": 2e-5},
                "intervals": {"backlash": [3e-5, 4e-5]},
            },
            "intervals.backlash: [3e-05, 4e-05] does not hold the parameter's value 2e-05",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "intervals": {"backlash": [1e-5]}},
            "intervals.backlash: expected a pair [low, high]",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "intervals": {"backlash": [3e-5, 1e-5]}},
            "intervals.backlash: low 3e-05 above high 1e-05",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "intervals": {"backlash": [-1.0, 1e-5]}},
            "intervals.backlash: -1 m outside the model's range",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "intervals": {"no_such": [0.0, 1.0]}},
            "intervals.no_such: not a parameter",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "model_error": {"position_peak_m": 1e-7}},
            "model_error: expected all of ['position_peak_m', 'position_rms_m', 'current_rms_A']",
        ),
        (
            {
                "model": "drive2mass",
                "parameters": {},
                "model_error": {**ERROR, "position_rms_m": -1},
            },
            "model_error.position_rms_m: expected a number >= 0",
        ),
        (
            {
                "model": "drive2mass",
                "parameters": {},
                "model_error": {**ERROR, "current_rms_A": math.inf},
            },
            "model_error.current_rms_A: expected a finite number",
        ),
        (
            {"model": "drive2mass", "parameters": {}, "model_error": {**ERROR, "peak_um": 0.1}},
            "model_error: unknown key(s) ['peak_um']",
        ),
        (
            {
                "model": "drive2mass",
                "parameters": {},
                "model_error": {**ERROR, "position_peak_m": 1e-8},
            },
            "model_error.position_peak_m: expected at least position_rms_m",
        ),
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


def test_a_plant_file_spells_out_every_value_without_yaml_anchors(tmp_path):
    """A value met twice (one group of effects behind two parameters) is written twice, never
    as an anchor and an alias a person editing the file must decode."""
    group = ["backlash_change", "coulomb_change"]
    plant = PlantParameters(
        "drive2mass",
        {"backlash": 2e-5, "coulomb_friction": 0.66},
        {
            "backlash": {"source": "a", "effect": group},
            "coulomb_friction": {"source": "b", "effect": group},
        },
    )
    path = write_plant_parameters(tmp_path / "plant.yaml", plant)
    text = path.read_text()
    assert "&id" not in text and "*id" not in text
    assert text.count("- backlash_change") == 2
    assert read_plant_parameters(path).provenance == plant.provenance


def test_a_hand_edited_plant_file_reads_as_a_scenario_does(tmp_path):
    """One loader: 2e-5 (no dot) is a number in plant.yaml as in a scenario, and a malformed
    file fails with the scenarios' error, naming the file."""
    path = tmp_path / "plant.yaml"
    path.write_text("model: drive2mass\nparameters:\n  backlash: 2e-5\n  stribeck_speed: 1e0\n")
    assert read_plant_parameters(path).parameters == {"backlash": 2e-5, "stribeck_speed": 1.0}
    path.write_text("model: drive2mass\nparameters: {backlash: [\n")
    with pytest.raises(ScenarioError, match=rf"^{path}: malformed YAML"):
        read_plant_parameters(path)
