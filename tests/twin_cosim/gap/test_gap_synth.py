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


@pytest.mark.parametrize("seed", [0, 7, 1000, 1003])
def test_random_excitations_cover_every_regime_within_the_axis_limits(seed):
    from twin_cosim.gap.synth import (
        EXCITATION_SAMPLE_PERIOD,
        EXCITATION_TRAVEL,
        covers_regimes,
        random_excitation,
    )
    from twin_cosim.reference import Ramp, interpolate, sample_segments
    from twin_cosim.scenario.machine import DEFAULT_LIMITS

    segments = random_excitation(seed)
    assert random_excitation(seed) == segments  # seeded
    samples = sample_segments(segments, EXCITATION_SAMPLE_PERIOD)
    grid = interpolate(samples, EXCITATION_SAMPLE_PERIOD, 250e-6)
    assert covers_regimes(grid)
    assert np.max(np.abs(samples)) <= EXCITATION_TRAVEL / 2
    assert np.max(np.abs(np.diff(samples))) / EXCITATION_SAMPLE_PERIOD <= DEFAULT_LIMITS.velocity
    for segment in segments:
        if hasattr(segment, "acceleration"):
            assert segment.acceleration <= DEFAULT_LIMITS.acceleration
    half = len(samples) // 2
    assert not np.allclose(samples[:half], samples[half : 2 * half])  # two different halves
    speeds = np.abs(np.diff(samples)) / EXCITATION_SAMPLE_PERIOD
    assert np.any((speeds > 1e-4) & (speeds < 3e-3))  # creeps
    assert any(isinstance(s, Ramp) for s in segments)


def test_covers_regimes_refuses_a_half_without_a_reversal():
    from twin_cosim.gap.synth import covers_regimes
    from twin_cosim.reference import Dwell, Move, interpolate, sample_segments

    out_and_back = [Dwell(0.3), Move(0.01, 0.02, 0.5), Dwell(0.3), Move(0.0, 0.02, 0.5)]
    one_way = [Dwell(0.3), Move(0.01, 0.02, 0.5), Dwell(0.3), Move(0.02, 0.02, 0.5)]
    grids = [
        interpolate(sample_segments(s + s, 0.004), 0.004, 250e-6) for s in (out_and_back, one_way)
    ]
    assert not covers_regimes(grids[0])  # no breakaway: every start turns back
    assert not covers_regimes(grids[1])  # no reversal


def test_synth_follows_a_random_excitation_and_writes_its_scenario(tmp_path, capsys):
    from twin_cosim.cli import main
    from twin_cosim.gap.synth import random_excitation
    from twin_cosim.reference import sample_segments
    from twin_cosim.scenario import resolve_scenario

    run = tmp_path / "run.csv"
    assert main(["synth", "diagnosis", "--random-excitation", "5", "--out", str(run)]) == 0
    followed = tmp_path / "run.csv.scenario.yaml"
    assert str(followed) in capsys.readouterr().out
    scenario = resolve_scenario(followed)
    expected = sample_segments(random_excitation(5), 0.004)
    assert np.allclose(scenario.reference.position[::16], expected)
    measured = np.loadtxt(run, delimiter=",", skiprows=1, usecols=1)  # x_ref
    assert np.allclose(measured[::16], expected)
    assert main(["synth", "diagnosis", "--random-excitation", "5", "--out", str(run)]) == 2
    assert "run.csv exists" in capsys.readouterr().err
    again = ["synth", "diagnosis", "--random-excitation", "5", "--follow", str(run)]
    assert main([*again, "--out", str(tmp_path / "b.csv")]) == 2
    assert "--random-excitation and --follow" in capsys.readouterr().err
