"""Noise harmonics and noise floor from standstill stretches separated by motion."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.noise import (
    Harmonic,
    as_plant_parameters,
    noise_floor,
    noise_harmonics,
    plant_slots,
)

DT = 250e-6  # s
T0 = 10.0  # s, the record starts late: phases are referenced to t = 0 (the frequency error
# times ~13 s adds to the phase error)
SIGMA = 0.01e-6  # m, white measurement noise
TRUE = [Harmonic(0.3e-6, 47.3, 0.7), Harmonic(0.1e-6, 123.7, -2.1), Harmonic(0.05e-6, 311.0, 2.9)]
# standstill stretches (s after T0); the one of 0.15 s is too short to be used
STILL = [(0.0, 1.2), (1.7, 2.5), (3.0, 3.3), (3.6, 3.75), (4.2, 6.0)]


def run(sigma: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), measured position (m) and standstill mask of dwells joined by moves."""
    rng = np.random.default_rng(seed)
    t = T0 + np.arange(round(6.0 / DT)) * DT
    mask = np.zeros(t.size, dtype=bool)
    for a, b in STILL:
        mask[round(a / DT) : round(b / DT)] = True
    motion = np.cumsum(~mask) * 2e-5  # 80 mm/s while moving, parked at other positions
    noise = sum(h.amplitude_m * np.sin(2 * np.pi * h.frequency_hz * t + h.phase_rad) for h in TRUE)
    return t, motion + noise + sigma * rng.standard_normal(t.size), mask


@pytest.mark.parametrize("seed", [0, 1])
def test_three_harmonics_recovered(seed):
    t, x, mask = run(sigma=SIGMA, seed=seed)
    found = noise_harmonics(t, x, mask)
    assert len(found) == 3
    for got, true in zip(found, TRUE, strict=True):
        assert got.amplitude_m == pytest.approx(true.amplitude_m, rel=0.03)
        assert got.frequency_hz == pytest.approx(true.frequency_hz, abs=0.1)
        assert got.phase_rad == pytest.approx(true.phase_rad, abs=0.05)


def test_runs_concatenated_with_the_time_restarting():
    first, second = run(sigma=SIGMA, seed=6), run(sigma=SIGMA, seed=7)
    t, x, mask = (np.concatenate(pair) for pair in zip(first, second, strict=True))
    assert mask[t.size // 2 - 1] and mask[t.size // 2]  # one standstill run across the seam
    found = noise_harmonics(t, x, mask)
    assert len(found) == 3
    for got, true in zip(found, TRUE, strict=True):
        assert got.amplitude_m == pytest.approx(true.amplitude_m, rel=0.03)
        assert got.phase_rad == pytest.approx(true.phase_rad, abs=0.05)


def test_count_limits_to_the_largest():
    t, x, mask = run(sigma=SIGMA, seed=2)
    found = noise_harmonics(t, x, mask, count=2)
    assert [round(h.frequency_hz) for h in found] == [47, 124]


def test_no_usable_standstill_or_no_peak():
    t, x, mask = run(sigma=SIGMA, seed=3)
    short = np.zeros_like(mask)
    short[100:500] = True  # 0.1 s
    assert noise_harmonics(t, x, short) == []
    rng = np.random.default_rng(4)
    assert noise_harmonics(t, 1e-8 * rng.standard_normal(t.size), mask) == []


def test_plant_parameters(plant):
    """As many slots as the FMU has; unused ones off, at the FMU's start values."""
    harmonics = [Harmonic(0.3e-6, 47.3, 0.7), Harmonic(0.1e-6, 123.7, 3.5)]
    start = plant.start_values()
    assert plant_slots(start) == 4
    parameters = as_plant_parameters(harmonics, start)
    assert set(parameters) == {
        f"noise_{kind}_{k}" for kind in ("amplitude", "frequency", "phase") for k in range(1, 5)
    }
    assert parameters["noise_amplitude_1"] == 0.3e-6
    assert parameters["noise_frequency_2"] == 123.7
    assert parameters["noise_phase_2"] == pytest.approx(3.5 - 2 * np.pi)
    assert [parameters[f"noise_amplitude_{k}"] for k in (3, 4)] == [0.0, 0.0]
    for k in (3, 4):
        assert parameters[f"noise_frequency_{k}"] == start[f"noise_frequency_{k}"]
        assert parameters[f"noise_phase_{k}"] == start[f"noise_phase_{k}"]
    with pytest.raises(ValueError, match="holds 4 noise harmonics"):
        as_plant_parameters(harmonics * 3, start)


def test_noise_floor_of_white_noise():
    rng = np.random.default_rng(5)
    _, _, mask = run(sigma=0.0, seed=0)
    offsets = np.cumsum(~mask) * 2e-5  # each stretch at its own position, large moves between
    residual = offsets + 0.2e-6 * rng.standard_normal(mask.size)
    assert noise_floor(residual, mask) == pytest.approx(0.2e-6, rel=0.1)
    assert noise_floor(residual, np.zeros_like(mask)) == 0.0
