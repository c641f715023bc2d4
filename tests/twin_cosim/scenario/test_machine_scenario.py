"""Machine scenarios (``axes:``): loaded into typed axes; every error names the file and key."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from twin_cosim import paper
from twin_cosim.reference import ReferenceGrid
from twin_cosim.scenario import ScenarioError, is_machine_scenario, load_machine


def _write(tmp_path, text: str):
    path = tmp_path / "machine.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_xy_table_has_two_drive2mass_axes_with_fine_tune():
    machine = load_machine("xy_table")
    assert machine.axis_names == ("X", "Y")
    for axis in machine.axes:
        assert axis.model == "drive2mass"
        assert axis.tuned == paper.FINE_TUNE
        assert axis.settings.position_period == 250e-6
    assert machine.sample_period == 0.004
    assert is_machine_scenario("xy_table") and not is_machine_scenario("reference1")


def test_each_axis_has_its_own_plant_parameters_and_controller(tmp_path):
    (tmp_path / "y_plant.yaml").write_text("model: drive2mass\nparameters: {backlash: 3.0e-5}\n")
    path = _write(
        tmp_path,
        """
        axes:
          X: {plant: {parameters: {coulomb_friction: 0.5}}, controller: {parameters: ga}}
          Y:
            plant: {parameters_file: y_plant.yaml}
            limits: {velocity: 0.1}
          Z: {}
        """,
    )
    machine = load_machine(path)
    x, y, z = machine.axes
    assert x.plant_parameters == {"coulomb_friction": 0.5}
    assert x.settings.friction_torque == 0.5  # the plant fact follows the axis' own plant
    assert x.tuned == paper.TABLE3["ga"]
    assert y.plant_parameters == {"backlash": 3.0e-5}
    assert y.limits.velocity == 0.1 and y.limits.acceleration == 2.0
    assert z.name == "Z"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("axes: {X: {}}", "axes.Y: expected a section"),
        ("axes: {X: {}, Y: {plant: {model: nope}}}", "axes.Y.plant.model"),
        ("axes: {X: {}, Y: {plant: {parameters: {backlash: x}}}}", "axes.Y.plant.parameters."),
        ("axes: {X: {}, Y: {limits: {jerk: 0}}}", "axes.Y.limits.jerk: expected a number > 0"),
        ("axes: {X: {gains: 1}, Y: {}}", "axes.X: unknown key(s) ['gains']"),
        ("axes: {X: {}, Y: {}, W: {}}", "axes: unknown key(s) ['W']"),
        (
            "axes: {X: {}, Y: {controller: {settings: {speed_period: 1.25e-4}}}}",
            "axes.Y.controller.settings.speed_period",
        ),
        ("axes: {X: {controller: {parameters: zz}}, Y: {}}", "axes.X.controller.parameters"),
        ("axes: {X: {}, Y: {}}\ninterpolation: {sample_period: 0.0013}", "interpolation.sample"),
    ],
)
def test_errors_name_the_file_and_the_key(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(ScenarioError) as error:
        load_machine(path)
    assert str(path) in str(error.value)
    assert message in str(error.value)


def test_an_axis_is_a_single_axis_scenario_once_its_reference_is_known():
    machine = load_machine("xy_table")
    grid = ReferenceGrid(250e-6, np.full(5, 0.01), np.zeros(5), np.zeros(5))
    scenario = machine.axis_scenario("Y", grid)
    assert scenario.plant_parameters["load_position_start"] == 0.01
    assert scenario.tuned == machine.axis("Y").tuned
    assert scenario.reference is grid
