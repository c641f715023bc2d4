"""The drive's plant facts come from the plant model's parameters: known values, exact relations."""

from __future__ import annotations

import math

import pytest
from emps_data import needs_emps_data
from fmpy import read_model_description

from fmu_build.build import build_fmu
from twin_cosim.controller import ControllerSettings
from twin_cosim.plant_facts import drive_facts, fmu_identity, model_start_values
from twin_cosim.scenario import load_scenario


def test_drive2mass_facts_are_the_papers_table1():
    facts = drive_facts(model_start_values("drive2mass"))
    assert facts["travel_per_rad"] == pytest.approx(0.010 / (2 * math.pi) / 1.5, rel=1e-15)
    assert facts["inertia"] == pytest.approx(2.9e-4 + 4.2e-4, rel=1e-15)
    assert (facts["torque_constant"], facts["friction_torque"]) == (0.74, 0.625)


def test_default_controller_settings_are_the_default_plants():
    settings = ControllerSettings()
    facts = drive_facts(model_start_values("drive2mass"))
    assert {name: getattr(settings, name) for name in facts} == facts


def test_linear_axis_feedforward_is_force_over_drive_gain():
    """Linear axis, motor-referred: J a / (travel K_t) = M a / g and F_C lead / K_t = F_C / g."""
    mass, gain, lead, coulomb = 95.1089, 35.15065188, 3.978873577297384e-4, 20.3935
    facts = drive_facts(
        {"mass": mass, "drive_gain": gain, "lead_per_rad": lead, "coulomb_friction": coulomb}
    )
    acceleration = 2.0  # m/s^2
    command = facts["inertia"] * acceleration / (facts["travel_per_rad"] * facts["torque_constant"])
    assert command == pytest.approx(mass * acceleration / gain, rel=1e-12)
    assert facts["friction_torque"] / facts["torque_constant"] == pytest.approx(coulomb / gain)


def test_model_table_and_built_fmu_agree(fmu_path):
    identifier, names, starts = fmu_identity(fmu_path)
    assert identifier == "drive2mass"
    assert starts == pytest.approx(model_start_values("drive2mass"))
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
    description = read_model_description(str(scenario.fmu or build_fmu(scenario.model)))
    assert float(description.defaultExperiment.stepSize) == scenario.settings.speed_period
