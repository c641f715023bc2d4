"""The friction curve: the fit against known curves, the twin's runs recovering a plant's
friction per direction (the goal), measured files of constant-speed runs, plant.yaml."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from twin_cosim.scenario import load_scenario
from twin_cosim.scenario.plant_parameters import read_plant_parameters
from twin_cosim.servo.friction import (
    FrictionDataError,
    FrictionPoint,
    fit_friction,
    friction_curve,
    measured_levels,
)

# A plant with other friction than Table 1: Coulomb per direction, viscous, a Stribeck rise that
# makes the load stick and slip between about 0.05 and 0.9 rad/s at the Table 1 coupling
PLANT = {
    "coulomb_friction": 0.45,
    "coulomb_asymmetry": -0.08,
    "viscous_friction": 0.003,
    "stribeck_friction": 0.15,
    "stribeck_speed": 0.4,
}
TRUTH = {
    "coulomb_positive": 0.37,
    "coulomb_negative": 0.53,
    "viscous": 0.003,
    "stribeck_friction": 0.15,
    "stribeck_speed": 0.4,
}


def curve(w: np.ndarray, truth: dict = TRUTH) -> np.ndarray:
    """The plant's friction torque (N.m) at signed motor speeds (rad/s)."""
    coulomb = np.where(w >= 0, truth["coulomb_positive"], truth["coulomb_negative"])
    rise = truth["stribeck_friction"] * np.exp(-((w / truth["stribeck_speed"]) ** 2))
    return np.sign(w) * (coulomb + rise + truth["viscous"] * np.abs(w))


def test_the_fit_of_points_on_the_curve_is_the_curve():
    w = np.concatenate([np.geomspace(30, 0.02, 25), -np.geomspace(30, 0.02, 25)])
    points = [
        FrictionPoint(float(v), float(t), 0.0, "steady level")
        for v, t in zip(w, curve(w), strict=True)
    ]
    fit, directions = fit_friction(points)
    for name, value in TRUTH.items():
        assert fit.values[name] == pytest.approx(value, rel=1e-6)
        assert fit.uncertainty[name] < 1e-6 * value
    assert directions["positive"].values["coulomb_positive"] == pytest.approx(0.37, rel=1e-6)
    assert directions["negative"].values["coulomb_negative"] == pytest.approx(0.53, rel=1e-6)
    assert directions["negative"].values["coulomb_positive"] is None


def test_a_curve_without_a_rise_has_no_stribeck_terms():
    flat = {**TRUTH, "stribeck_friction": 0.0}
    w = np.concatenate([np.geomspace(30, 0.05, 12), -np.geomspace(30, 0.05, 12)])
    points = [
        FrictionPoint(float(v), float(t), 0.0, "steady level")
        for v, t in zip(w, curve(w, flat), strict=True)
    ]
    fit, _ = fit_friction(points)
    assert fit.values["stribeck_friction"] is None and "stribeck_speed" in fit.not_identified
    assert fit.values["coulomb_negative"] == pytest.approx(0.53, rel=1e-6)
    assert fit.values["viscous"] == pytest.approx(0.003, rel=1e-5)


def test_the_twin_recovers_the_plants_friction_per_direction(plant):
    """Goal: Coulomb, viscous and Stribeck levels per direction within 5 %, the Stribeck speed
    within 15 %, on a plant whose load sticks and slips at the lower speeds."""
    scenario = load_scenario("reference1")
    scenario = dataclasses.replace(
        scenario, plant_parameters={**scenario.plant_parameters, **PLANT}
    )
    result = friction_curve(plant, scenario, np.geomspace(28.0, 0.02, 24))
    kinds = {p.kind for p in result.points}
    assert kinds == {"steady level", "stick-slip level", "torque balance"}
    for fit in (result.fit, result.directions["positive"], result.directions["negative"]):
        for name, value in TRUTH.items():
            if fit.values[name] is not None:
                tolerance = 0.15 if name == "stribeck_speed" else 0.05
                assert fit.values[name] == pytest.approx(value, rel=tolerance), name
    assert result.fit.values["stribeck_speed"] is not None


def synthetic_runs(path, noise: float, seed: int = 0):
    """A measured file of constant-speed runs at 1 kHz: levels each way, 0.1 s ramps between
    them, torque = friction + J dw/dt, noise on speed (rad/s) and torque (N.m)."""
    rng = np.random.default_rng(seed)
    dt, inertia = 1e-3, 7.1e-4
    speeds = []
    for sign in (1, -1):
        w = 0.0
        for level in np.geomspace(25.0, 0.8, 10):
            target = sign * level
            speeds.append(np.linspace(w, target, 100, endpoint=False))  # 0.1 s ramp
            speeds.append(np.full(500, target))  # 0.5 s held
            w = target
        speeds.append(np.linspace(w, 0.0, 100))
    w = np.concatenate(speeds)
    torque = curve(w) + inertia * np.gradient(w, dt)
    frame = pd.DataFrame(
        {
            "t": np.arange(len(w)) * dt,
            "motor_speed": w + noise * rng.normal(size=len(w)),
            "torque": torque + 0.1 * noise * rng.normal(size=len(w)),
        }
    )
    frame.to_csv(path, index=False)
    return path


def test_measured_levels_are_the_held_speeds_without_their_ramps(tmp_path):
    scenario = load_scenario("reference1")
    points = measured_levels(synthetic_runs(tmp_path / "runs.csv", 0.02), scenario)
    assert len(points) == 20
    speeds = np.array([p.speed for p in points])
    torques = np.array([p.torque for p in points])
    np.testing.assert_allclose(torques, curve(speeds), atol=2e-3)
    fit, _ = fit_friction(points)
    assert fit.values["coulomb_negative"] == pytest.approx(0.53, rel=0.02)
    assert fit.values["viscous"] == pytest.approx(0.003, rel=0.05)


def test_friction_command_on_a_measured_file_and_a_bad_one(twin_cli, tmp_path):
    runs = synthetic_runs(tmp_path / "runs.csv", 0.0)
    result = twin_cli(
        "friction", "reference1", "--measured", str(runs), "--out", str(tmp_path / "f"), "--json"
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    for name in ("coulomb_positive", "coulomb_negative", "viscous", "stribeck_friction"):
        assert summary[name] == pytest.approx(TRUTH[name], rel=0.02)
        assert summary["uncertainty"][name] >= 0
    plant = read_plant_parameters(tmp_path / "f" / "plant.yaml", "drive2mass").parameters
    assert plant["coulomb_friction"] == pytest.approx(0.45, rel=0.02)
    assert plant["coulomb_asymmetry"] == pytest.approx(-0.08, rel=0.05)
    for name in ("friction.png", "friction.txt", "friction.csv", "friction.json"):
        assert (tmp_path / "f" / name).is_file()
    bad = tmp_path / "bad.csv"
    bad.write_text("t,motor_speed\n" + "".join(f"{k * 0.001},1.0\n" for k in range(20)))
    result = twin_cli("friction", "reference1", "--measured", str(bad), "--out", str(tmp_path))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "bad.csv: expected a column torque [N.m] or current [A]" in result.stderr


def test_a_measured_value_that_is_not_a_number_is_named(tmp_path):
    path = tmp_path / "nan.csv"
    rows = "\n".join(f"{k * 0.001},{'x' if k == 7 else 1.0},0.5" for k in range(20))
    path.write_text("t,motor_speed,torque\n" + rows + "\n")
    with pytest.raises(FrictionDataError, match="column motor_speed: 'x' in data row 8"):
        measured_levels(path, load_scenario("reference1"))
