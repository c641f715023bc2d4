"""The plant-model card: the drive's plant facts from the model's parameters (known values,
exact relations), its effect library against the FMU's variables, its errors.

The effect library's mappings to FMU parameters, against their formulas.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from emps_data import needs_emps_data
from fmpy import read_model_description

from fmu_build.build import MODELS_DIR, build_fmu
from twin_cosim.controller import ControllerSettings
from twin_cosim.plant import Plant, PlantError
from twin_cosim.plant_model import (
    PlantModelError,
    effects_table,
    fmu_identity,
    model_names,
    plant_model,
    read_card,
)
from twin_cosim.scenario import load_scenario


def test_drive2mass_facts_are_the_papers_table1():
    facts = plant_model("drive2mass").drive_facts()
    assert facts["travel_per_rad"] == pytest.approx(0.010 / (2 * math.pi) / 1.5, rel=1e-15)
    assert facts["inertia"] == pytest.approx(2.9e-4 + 4.2e-4, rel=1e-15)
    assert (facts["torque_constant"], facts["friction_torque"]) == (0.74, 0.625)


def test_default_controller_settings_are_the_default_plants():
    settings = ControllerSettings()
    facts = plant_model("drive2mass").drive_facts()
    assert {name: getattr(settings, name) for name in facts} == facts


def test_linear_axis_feedforward_is_force_over_drive_gain():
    """Linear axis, motor-referred: J a / (travel K_t) = M a / g and F_C lead / K_t = F_C / g."""
    mass, gain, lead, coulomb = 95.1089, 35.15065188, 3.978873577297384e-4, 20.3935
    facts = plant_model("emps").drive_facts(
        {"mass": mass, "drive_gain": gain, "lead_per_rad": lead, "coulomb_friction": coulomb}
    )
    acceleration = 2.0  # m/s^2
    command = facts["inertia"] * acceleration / (facts["travel_per_rad"] * facts["torque_constant"])
    assert command == pytest.approx(mass * acceleration / gain, rel=1e-12)
    assert facts["friction_torque"] / facts["torque_constant"] == pytest.approx(coulomb / gain)


def test_model_table_and_built_fmu_agree(fmu_path):
    identifier, names, starts = fmu_identity(fmu_path)
    assert identifier == "drive2mass"
    assert starts == pytest.approx(plant_model("drive2mass").start_values())
    assert "motor_inertia" in names


@pytest.mark.parametrize(
    "name",
    [
        "reference1",
        "reference2",
        "diagnosis",
        pytest.param("emps", marks=needs_emps_data),  # its reference is the EMPS data
    ],
)
def test_speed_loop_step_is_the_fmus_default_step(name):
    """The speed-loop period of a shipped scenario is the DefaultExperiment step of its FMU."""
    scenario = load_scenario(name)
    description = read_model_description(str(scenario.plant_fmu()))
    assert float(description.defaultExperiment.stepSize) == scenario.settings.speed_period


@pytest.mark.parametrize("model", model_names())
def test_every_effect_sets_parameters_of_the_fmu_within_their_ranges(model):
    """Each hypothesis at its start, its bounds and mid-range maps to FMU parameters of the
    model's variable table, inside their ranges (the library and the FMU block agree)."""
    card = plant_model(model)
    nominal, parameters = card.start_values(), card.parameters
    context = {"motor_order": 6.0, "screw_order": 1.0}
    for hypothesis in card.hypotheses:
        for u in (hypothesis.initial_unit(), np.full(len(hypothesis.parameters), 0.5)):
            for name, value in hypothesis.to_plant(
                hypothesis.from_unit(u), nominal, context
            ).items():
                variable = parameters[name]
                low = -math.inf if variable.min is None else variable.min
                high = math.inf if variable.max is None else variable.max
                assert low <= value <= high, (hypothesis.name, name, value)


@pytest.mark.parametrize("model", model_names())
def test_the_readme_shows_the_cards_effect_library(model):
    readme = (MODELS_DIR / model / "README.md").read_text()
    assert effects_table(model) in readme


def test_the_screw_angle_is_the_motor_angle_over_the_gear_ratio():
    card = plant_model("drive2mass")
    assert card.motor_per_screw(card.start_values()) == 1.5  # Table 1: NP121/NP122 = 3/2
    assert plant_model("emps").motor_per_screw(plant_model("emps").start_values()) == 1.0


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            ("travel_per_rad: spindle_constant / gear_ratio", "travel_per_rad: spindle / 2"),
            "drive.travel_per_rad: expected a formula",
        ),
        (
            (
                "backlash: nominal.backlash + delta_backlash",
                "backlash: nominal.lash + delta_backlash",
            ),
            "effects.backlash_change.sets.backlash",
        ),
        (
            ("coulomb_asymmetry: coulomb_asymmetry", "no_such_block: coulomb_asymmetry"),
            "effects.asymmetric_friction.sets: expected FMU parameters",
        ),
        (("scan: whole_numbers", "scan: every_other"), "effects.dead_time.scan: expected one of"),
        (("upper: 8.0}", "upper: 0.5}"), "effects.dead_time.parameters[0]: expected lower"),
        (("model: drive2mass", "model: other"), "model: expected 'drive2mass'"),
    ],
)
def test_a_bad_card_is_refused_naming_the_file_and_key(tmp_path, edit, message):
    text = (MODELS_DIR / "drive2mass" / "card.yaml").read_text()
    assert edit[0] in text
    card = tmp_path / "card.yaml"
    card.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(PlantModelError) as error:
        read_card(card, "drive2mass", plant_model("drive2mass").table)
    assert str(error.value).startswith(f"{card}: ")
    assert message in str(error.value)


@pytest.mark.parametrize(
    ("model", "values", "says"),
    [
        ("drive2mass", {"coulomb_friction": 0.01, "coulomb_asymmetry": 0.02}, "coulomb"),
        ("emps", {"viscous_friction": 100.0, "viscous_asymmetry": -150.0}, "viscous"),
        ("hsm150", {"coulomb_friction": 0.02, "coulomb_asymmetry": -0.03}, "coulomb"),
        ("hsm150", {"viscous_asymmetry": 1e-4}, "viscous"),
    ],
)
def test_the_cards_constraints_are_what_the_fmu_refuses(model, values, says):
    """Values within their ranges that break a constraint of the card: the card names the
    relation and the values, and the FMU refuses them too; halved, both accept them."""
    card = plant_model(model)
    [(text, names)] = card.broken_constraints(values)
    assert f"|{says}_asymmetry| <= {says}_friction" in text
    assert set(names) == {f"{says}_asymmetry", f"{says}_friction"}
    with Plant(build_fmu(model), model) as plant:
        with pytest.raises(PlantError, match="asymmetr"):
            plant.start_run(values)
        fine = {**values, f"{says}_asymmetry": values[f"{says}_asymmetry"] / 2}
        fine = fine if f"{says}_friction" in values else values | {f"{says}_asymmetry": 3e-5}
        assert card.broken_constraints(fine) == []
        plant.start_run(fine)


def test_an_unknown_model_is_refused_with_the_known_ones():
    with pytest.raises(PlantModelError, match=r"unknown plant model 'nope': expected one of"):
        plant_model("nope")


LIBRARY = plant_model("drive2mass").hypotheses
BY_NAME = {h.name: h for h in LIBRARY}

NOMINAL = {
    "coulomb_friction": 0.625,
    "backlash": 12.2e-6,
    "motor_inertia": 2.9e-4,
    "load_inertia": 4.2e-4,
    "resonance_frequency": 70.0,
}
CONTEXT = {"motor_order": 6.0, "screw_order": 1.0, "position_resolution": 0.0}


def test_library_names_and_units():
    assert len(LIBRARY) == len(BY_NAME) > 0  # names are unique
    for hypothesis in LIBRARY:
        assert 1 <= len(hypothesis.parameters) <= 4
        u = hypothesis.initial_unit()
        assert np.all((u >= 0) & (u <= 1))


@pytest.mark.parametrize("name", ["pitch_error", "torque_ripple"])
def test_cos_sin_parts_map_to_amplitude_and_phase(name):
    hypothesis = BY_NAME[name]
    values = np.array([0.0, 3e-6, -4e-6]) if name == "pitch_error" else np.array([3.0, -4.0])
    params = hypothesis.to_plant(values, NOMINAL, CONTEXT)
    prefix = "pitch_error" if name == "pitch_error" else "ripple"
    amplitude = params[f"{prefix}_amplitude{'_1' if name == 'pitch_error' else ''}"]
    phase = params[f"{prefix}_phase{'_1' if name == 'pitch_error' else ''}"]
    for u in np.linspace(0, 2 * math.pi, 7):
        fitted = values[-2] * math.cos(u) + values[-1] * math.sin(u)
        assert amplitude * math.sin(u + phase) == pytest.approx(fitted, abs=1e-12)


def test_inertia_change_keeps_the_coupling_stiffness():
    params = BY_NAME["inertia_change"].to_plant(np.array([0.21]), NOMINAL, CONTEXT)
    stiffness = params["load_inertia"] * (2 * math.pi * params["resonance_frequency"]) ** 2
    assert stiffness == pytest.approx(NOMINAL["load_inertia"] * (2 * math.pi * 70.0) ** 2)
    assert params["motor_inertia"] == pytest.approx(2.9e-4 * 1.21)


def test_calibration_sizes():
    assert BY_NAME["stiffness_change"].relative_size(np.array([0.21]), NOMINAL) == pytest.approx(
        0.1
    )
    assert BY_NAME["backlash_change"].relative_size(np.array([1.22e-6]), NOMINAL) == pytest.approx(
        0.1
    )
    # a friction torque beside the Coulomb level: its largest torque over that level
    coulomb = NOMINAL["coulomb_friction"]
    stribeck = BY_NAME["stribeck"].relative_size(np.array([0.1 * coulomb, 0.5]), NOMINAL)
    assert stribeck == pytest.approx(0.1)
    asymmetry = BY_NAME["asymmetric_friction"].relative_size(np.array([-0.1 * coulomb]), NOMINAL)
    assert asymmetry == pytest.approx(0.1)
    modulation = BY_NAME["position_friction"].relative_size(np.array([0.06, 0.08]), NOMINAL)
    assert modulation == pytest.approx(0.1)
    assert BY_NAME["torque_ripple"].relative_size is None


def test_the_emps_friction_effects_are_sized_against_its_calibrated_friction():
    """The same rule on the EMPS axis: a Stribeck rise over its Coulomb level, the direction
    asymmetry's two parts over the Coulomb and viscous levels they modulate."""
    emps = {h.name: h for h in plant_model("emps").hypotheses}
    nominal = {"coulomb_friction": 20.0, "viscous_friction": 200.0}  # N, N.s/m
    stribeck = emps["stribeck"].relative_size(np.array([0.06, 2e-3]), nominal)
    assert stribeck == pytest.approx(0.003)  # within a 3 % tolerance: no size
    asymmetry = emps["asymmetric_friction"].relative_size(np.array([1.2, -32.0]), nominal)
    assert asymmetry == pytest.approx(math.hypot(0.06, 0.16))
