"""The ballbar's diagnostics: each error built into a path by its kinematics (not by its
signature) comes back from the circle; a twin with geometric errors and backlash gives them
back, its backlash figure what its axes show."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from twin_cosim.contour.ballbar import ballbar_figures
from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, evaluate_circle, run_circle
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import load_machine
from twin_cosim.scenario.machine import CyclicError, MachineGeometry

R = 0.05  # m
SPEED = 1000 * MM_PER_MIN  # m/s


def _path(direction: str, geometry: MachineGeometry, lag=(0.0, 0.0), lost=(0.0, 0.0), play=0.0):
    """A circle's data as the tool runs it: the axes follow their references ``lag`` (s) late,
    each loses ``lost`` (m) of motion at its reversals, the X carriage shifts by ``play`` (m)
    along Y as X reverses, and the geometry moves the axes' positions to the tool."""
    sign = 1.0 if direction == "ccw" else -1.0
    omega = SPEED / R
    t = np.arange(0.0, 2 * math.pi / omega, 2e-4)
    start = math.radians(45.0)

    def angle(delay):
        return start + sign * omega * (t - delay)

    x, y = R * np.cos(angle(lag[0])), R * np.sin(angle(lag[1]))
    vx, vy = -sign * np.sin(angle(lag[0])), sign * np.cos(angle(lag[1]))
    x = x - lost[0] / 2 * np.sign(vx)
    y = y - lost[1] / 2 * np.sign(vy) + play / 2 * np.sign(vx)
    tool_x, tool_y = geometry.tool_point(x, y)
    return RunRecord.from_columns(
        {"t": t, "x": tool_x, "y": tool_y}, {"t": "s", "x": "m", "y": "m"}
    )


IDEAL = MachineGeometry()


def _figures(geometry=IDEAL, directions=("ccw", "cw"), periods=None, **errors):
    results = [evaluate_circle(_path(d, geometry, **errors), R, d, SPEED) for d in directions]
    return ballbar_figures(results, R, periods or {"X": 0.01, "Y": 0.01})


def test_an_ideal_circle_has_no_error():
    figures = _figures()
    for key in ("squareness_um_per_m", "scale_mismatch_um_per_m", "servo_mismatch_ms"):
        assert abs(figures[key]) < 1e-6
    assert all(abs(v) < 1e-6 for e in figures["backlash_um"].values() for v in e.values())


def test_squareness_scale_and_straightness_come_back_in_their_units():
    travel = {"X": (-0.4, 0.4), "Y": (-0.3, 0.5)}
    geometry = MachineGeometry(
        squareness=30e-6, scale={"X": 20e-6, "Y": -12e-6}, straightness={"X": 8e-6, "Y": -5e-6},
        travel=travel,
    )  # fmt: skip
    figures = _figures(geometry)
    # Y's bow about the middle of its travel (0.1 m) tilts Y where the circle is, by
    # 2 b c / h^2 = 2 (-5 um) (0.1 m) / (0.4 m)^2 = -6.25 um/m: a squareness to the ballbar
    assert figures["squareness_um_per_m"] == pytest.approx(30.0 + 6.25, rel=2e-3)
    assert figures["scale_mismatch_um_per_m"] == pytest.approx(32.0, rel=2e-3)  # X minus Y
    # a bow b over a travel of half-length h is b (R/h)^2 over the circle's diameter
    assert figures["straightness_um"]["X"] == pytest.approx(8.0 * (0.05 / 0.4) ** 2, rel=0.02)
    assert figures["straightness_um"]["Y"] == pytest.approx(-5.0 * (0.05 / 0.4) ** 2, rel=0.02)
    assert abs(figures["servo_mismatch_ms"]) < 1e-4


def test_servo_mismatch_flips_with_the_direction_and_squareness_does_not():
    lagging = _figures(lag=(0.010, 0.016))  # Y 6 ms behind X
    assert lagging["servo_mismatch_ms"] == pytest.approx(6.0, rel=0.01)
    assert abs(lagging["squareness_um_per_m"]) < 0.05
    square = _figures(MachineGeometry(squareness=-40e-6))
    assert square["squareness_um_per_m"] == pytest.approx(-40.0, rel=2e-3)
    assert abs(square["servo_mismatch_ms"]) < 1e-4
    one = _figures(lag=(0.010, 0.016), directions=("ccw",))
    assert one["servo_mismatch_ms"] is None and one["lateral_play_um"] is None
    assert one["notes"]  # the 45-degree ellipse reported as squareness: said


def test_lost_motion_is_the_backlash_at_both_ends_of_each_axis():
    figures = _figures(lost=(6e-6, 2.5e-6))
    for end in ("positive", "negative"):
        assert figures["backlash_um"]["X"][end] == pytest.approx(6.0, rel=0.02)
        assert figures["backlash_um"]["Y"][end] == pytest.approx(2.5, rel=0.02)
    assert abs(figures["squareness_um_per_m"]) < 0.5 and abs(figures["servo_mismatch_ms"]) < 1e-3


def test_lateral_play_and_cyclic_error():
    figures = _figures(play=3e-6)
    assert figures["lateral_play_um"]["X"] == pytest.approx(3.0, rel=0.02)
    assert abs(figures["lateral_play_um"]["Y"]) < 0.05
    cyclic = MachineGeometry(cyclic={"Y": CyclicError(1.5e-6, 0.01)})
    figures = _figures(cyclic)
    assert figures["cyclic_error_um"]["Y"] == pytest.approx(1.5, rel=0.01)
    assert figures["cyclic_error_um"]["X"] < 0.02
    assert figures["cyclic_period_mm"] == {"X": 10.0, "Y": 10.0}
    small = _figures(cyclic, periods={"X": 0.2, "Y": 0.2})  # beyond the diameter: not fitted
    assert small["cyclic_error_um"] == {"X": None, "Y": None} and small["notes"]


def _axis_steps(run) -> dict[str, dict[str, float]]:
    """What an axis' own record shows of lost motion: its following error after a reversal
    minus before it (outward in the direction of travel), away from the spike (40-80 degrees
    either side of the transition), um."""
    contour = run.record.contour
    sign = 1.0 if run.spec.direction == "ccw" else -1.0
    angle = np.degrees(np.arctan2(contour["y_ref"], contour["x_ref"])) % 360
    steps: dict[str, dict[str, float]] = {"X": {}, "Y": {}}
    for transition, axis, end, outward in (
        (0.0, "X", "positive", 1.0),
        (180.0, "X", "negative", -1.0),
        (90.0, "Y", "positive", 1.0),
        (270.0, "Y", "negative", -1.0),
    ):
        error = (contour[axis.lower()] - contour[f"{axis.lower()}_ref"]) * 1e6
        travelled = (sign * (angle - transition) + 180) % 360 - 180
        after = error[(travelled > 40) & (travelled < 80) & run.data].mean()
        before = error[(travelled < -40) & (travelled > -80) & run.data].mean()
        steps[axis][end] = outward * (after - before)
    return steps


HIDDEN = """
axes:
  X:
    plant: {parameters: {backlash: 25.0e-6}}
    controller: CONTROLLER
    limits: {travel: [-0.4, 0.4]}
  Y:
    plant: {parameters: {backlash: 6.0e-6}}
    controller: {parameters: ft}
    limits: {travel: [-0.4, 0.4]}
geometry:
  squareness: 25.0
  scale: {X: 12.0, Y: -8.0}
"""


@pytest.mark.parametrize(
    "controller",
    [
        "{parameters: ft}",  # integral speed loop, reversal pulse: the backlash a spike only
        "{parameters: {Kp_pos: 66.67, Kp_vel: 0.2865, Ki_vel: 0.0, PP2: 0.0, PP3: 0.0082, "
        "f_H: 0.1}, settings: {friction_torque: 0.0}}",  # no integral, no friction feedforward
    ],
)
def test_a_twin_gives_back_its_geometry_and_what_its_axes_show_of_backlash(tmp_path, controller):
    path = tmp_path / "hidden.yaml"
    path.write_text(textwrap.dedent(HIDDEN).replace("CONTROLLER", controller))
    machine = load_machine(path)
    runs = []
    with MachinePlants(machine) as plants:
        for direction in ("ccw", "cw"):
            spec = CircleSpec(0.025, 2000 * MM_PER_MIN, direction)
            runs.append(run_circle(machine, plants, spec))
    figures = ballbar_figures([r.result for r in runs], 0.025, {"X": 0.01, "Y": 0.01})
    if "ft" in controller:  # alike axes: the ellipses are the geometry's
        assert figures["squareness_um_per_m"] == pytest.approx(25.0, rel=0.02)
        assert figures["scale_mismatch_um_per_m"] == pytest.approx(20.0, rel=0.02)
    steps = [_axis_steps(run) for run in runs]
    for axis in ("X", "Y"):
        for end in ("positive", "negative"):
            shown = np.mean([s[axis][end] for s in steps])
            assert figures["backlash_um"][axis][end] == pytest.approx(shown, rel=0.1, abs=0.5)
    if "Ki_vel: 0.0" in controller:  # friction against a P speed loop: a lost motion
        assert figures["backlash_um"]["X"]["positive"] > 5.0
    assert (
        figures["reversal_spikes_um"]["X"]["positive"]
        > figures["reversal_spikes_um"]["Y"]["positive"]
    )  # the larger backlash, the larger spike
