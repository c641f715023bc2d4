"""The virtual machine: effect parsing, calibration error, noise, output format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.synth import parse_effect, synthesize
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import load_scenario

REFERENCE1 = Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("friction:a=1", "unknown effect 'friction'"),
        ("stribeck:", "at least one param=value"),
        ("stribeck:stribeck_friction=lots", "must be param=number"),
        ("stribeck:stribeck_friction=nan", "finite number"),
    ],
)
def test_effect_syntax_errors(text, message):
    with pytest.raises(ValueError, match=message):
        parse_effect(text)


def test_effect_with_wrong_parameters():
    scenario = load_scenario(REFERENCE1)
    with pytest.raises(ValueError, match="missing"):
        synthesize(scenario, [parse_effect("inertia_change:delta=0.1")])


def test_synthetic_run_format_and_truth(plant):
    scenario = load_scenario(REFERENCE1)
    result = synthesize(
        scenario,
        [parse_effect("backlash_change:delta_backlash=5e-6")],
        perturb=0.03,
        seed=4,
        noise_position=0.0,
        noise_current=0.0,
    )
    assert list(result.run.columns) == ["t", "x_ref", "x", "current", "motor_speed"]
    factors = result.truth["calibration_factors"]
    assert set(factors) == set(plant_model("drive2mass").calibrated)
    assert all(abs(f - 1) <= 0.03 for f in factors.values())
    assert result.truth["plant_parameters"]["backlash"] == pytest.approx(
        12.2e-6 * factors["backlash"] + 5e-6
    )
    parameters = result.truth["plant_parameters"]
    replay = run_scenario(plant, scenario, plant_overrides=parameters)
    np.testing.assert_array_equal(replay["x"], result.run["x"])


def test_noise_is_seeded_and_white():
    scenario = load_scenario(REFERENCE1)
    a = synthesize(scenario, [], seed=1, noise_position=1e-7)
    b = synthesize(scenario, [], seed=1, noise_position=1e-7)
    c = synthesize(scenario, [], seed=2, noise_position=1e-7)
    assert np.array_equal(a.run.to_numpy(), b.run.to_numpy())
    assert not np.array_equal(a.run.to_numpy(), c.run.to_numpy())
    clean = synthesize(scenario, [], seed=1, noise_position=0.0, noise_current=0.0)
    noise = a.run["x"] - clean.run["x"]
    assert noise.std(ddof=1) == pytest.approx(1e-7, rel=0.05)


def test_encoder_readings_stay_on_their_grid():
    scenario = load_scenario(REFERENCE1)
    result = synthesize(
        scenario,
        [parse_effect("quantization:position_resolution=1e-6")],
        seed=3,
        noise_position=2e-7,
    )
    x = result.run["x"]
    assert np.max(np.abs(x / 1e-6 - np.round(x / 1e-6))) < 1e-6
