"""Machine scenarios (``axes:``): loaded into typed axes; every error names the file and key."""

from __future__ import annotations

import dataclasses
import textwrap

import numpy as np
import pytest

from twin_cosim.controller_set import FINE_TUNE, TABLE3
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
        assert axis.tuned == FINE_TUNE
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
    assert x.tuned == TABLE3["ga"]
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
        ("axes: {X: {limits: {travel: [0.1, 0.5]}}, Y: {}}", "axes.X.limits.travel: expected"),
        ("axes: {X: {limits: {travel: 0.5}}, Y: {}}", "axes.X.limits.travel: expected [low"),
        ("axes: {X: {}, Y: {}}\ninterpolation: {path_mode: G62}", "interpolation.path_mode"),
        ("axes: {X: {}, Y: {}}\ninterpolation: {tolerance: 1.0e-5}", "interpolation.tolerance"),
        ("axes: {X: {}, Y: {}}\ninterpolation: {look_ahead: 0}", "interpolation.look_ahead"),
        ("axes: {X: {}, Y: {}}\ngeometry: {scale: {X: a}}", "geometry.scale.X: expected a number"),
        ("axes: {X: {}, Y: {}}\ngeometry: {straightness: {X: 2}}", "axes.X.limits.travel"),
        ("axes: {X: {}, Y: {}}\ngeometry: {cyclic: {Y: {amplitude_um: 1}}}", "cyclic.Y.period"),
        ("axes: {X: {}, Y: {}}\ngeometry: {roll: 1}", "geometry: unknown key(s) ['roll']"),
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


def test_travel_path_control_and_geometry_are_read_in_their_units(tmp_path):
    path = _write(
        tmp_path,
        """
        axes:
          X: {limits: {travel: [-0.3, 0.5]}}
          Y: {limits: {travel: [-0.2, 0.2]}}
        interpolation: {path_mode: G64, tolerance: 1.0e-5, look_ahead: 50}
        geometry:
          squareness: 20.0
          scale: {X: 15.0}
          straightness: {Y: 3.0}
          cyclic: {X: {amplitude_um: 1.5, period_mm: 5.0}}
        """,
    )
    machine = load_machine(path)
    assert machine.limits["X"].travel == (-0.3, 0.5)
    assert machine.path_control.describe() == "G64 P0.01"
    assert machine.path_control.merge_tolerance == 5e-6 and machine.look_ahead == 50
    geometry = machine.geometry
    assert geometry.squareness == pytest.approx(20e-6)
    assert geometry.scale == {"X": pytest.approx(15e-6)}
    assert geometry.straightness["Y"] == pytest.approx(3e-6)
    assert geometry.cyclic["X"].amplitude == pytest.approx(1.5e-6)
    assert geometry.cyclic["X"].period == pytest.approx(5e-3)
    assert geometry.as_dict()["cyclic"] == {"X": {"amplitude_um": 1.5, "period_mm": 5.0}}
    shipped = load_machine("xy_table")
    assert shipped.path_control.describe() == "G61" and shipped.geometry.is_ideal
    assert all(axis.limits.travel == (-0.4, 0.4) for axis in shipped.axes)


def test_the_geometry_moves_the_tool_as_its_signs_say():
    machine = load_machine("xy_table")
    square = dataclasses.replace(machine.geometry, squareness=1e-3)  # the angle X-Y: obtuse
    x, y = square.tool_point(np.array([0.0, 0.01]), np.array([0.01, 0.0]))
    # +Y runs along (-1e-3, 1): the tool at Y = 10 mm leans towards -X
    assert x[0] == pytest.approx(-1e-5) and y[0] == pytest.approx(0.01)
    assert x[1] == pytest.approx(0.01) and y[1] == 0.0
    bow = dataclasses.replace(machine.geometry, straightness={"X": 2e-6}, travel={"X": (-0.4, 0.4)})
    _, y = bow.tool_point(np.array([-0.4, 0.0, 0.4]), np.zeros(3))
    assert y == pytest.approx([0.0, 2e-6, 0.0], abs=1e-18)  # 0 at the ends, the bow mid-travel


def test_a_single_axis_scenario_is_not_a_machine_and_the_error_says_so():
    with pytest.raises(ScenarioError) as error:
        load_machine("reference1")
    message = str(error.value)
    assert "needs a machine scenario" in message and "axes:" in message and "xy_table" in message
    assert "unknown key" not in message
