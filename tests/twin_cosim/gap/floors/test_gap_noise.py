"""The noise stage: harmonics and floors from standstill stretches separated by motion;
harmonics that cannot be identified are dropped, floors come from the data, and noise alone is
not a gap."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.data.regimes import CONSTANT_VELOCITY, STANDSTILL
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors import noise as noise_module
from twin_cosim.gap.floors.noise import (
    Floors,
    Harmonic,
    as_plant_parameters,
    compare_metrics,
    high_frequency_sigma,
    identify_noise,
    noise_floor,
    noise_floors,
    noise_harmonics,
    plant_slots,
)
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.measured import MeasuredRun
from twin_cosim.run_record import RunRecord

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


def residuals(position, current, regime=STANDSTILL) -> Residuals:
    n = len(position)
    t = np.arange(n) * DT
    return Residuals(
        t,
        np.asarray(position, float),
        np.asarray(current, float),
        np.full(n, regime),
        np.zeros(n),
        np.zeros(n),
        np.zeros(n),
    )


RANGES = {
    **{f"noise_amplitude_{k}": (0.0, 1e-3) for k in range(1, 5)},
    **{f"noise_frequency_{k}": (0.0, 1e6) for k in range(1, 5)},
    **{f"noise_phase_{k}": (-100.0, 100.0) for k in range(1, 5)},
}
START = {
    **{f"noise_amplitude_{k}": 0.0 for k in range(1, 5)},
    **{f"noise_frequency_{k}": 50.0 * k for k in range(1, 5)},
    **{f"noise_phase_{k}": 0.0 for k in range(1, 5)},
}


def test_a_harmonic_with_a_negative_frequency_is_dropped_and_reported(monkeypatch):
    """The crash of issue 10: noise_frequency_1 = -2.8865 reached the FMU."""
    found = [Harmonic(3e-8, -2.8865, 0.1), Harmonic(2e-8, 120.0, 0.2)]
    monkeypatch.setattr(noise_module, "noise_harmonics", lambda *a, **k: found)
    model = identify_noise(residuals(np.zeros(4000), np.zeros(4000)), DT, RANGES, START)
    assert [h.frequency_hz for h in model.harmonics] == [120.0]
    assert model.plant_parameters["noise_frequency_1"] == 120.0
    assert len(model.dropped) == 1 and "-2.886" in model.dropped[0]
    for name, value in model.plant_parameters.items():
        low, high = RANGES[name]
        assert low <= value <= high


def test_a_harmonic_outside_the_variable_range_is_dropped():
    rng = np.random.default_rng(0)
    t = np.arange(8000) * DT
    position = 1e-7 * np.sin(2 * np.pi * 60.0 * t) + rng.normal(0, 2e-9, t.size)
    narrow = {**RANGES, "noise_frequency_1": (0.0, 50.0)}
    model = identify_noise(residuals(position, np.zeros_like(t)), DT, narrow, START)
    assert model.harmonics == []
    assert "noise_frequency_1" in model.dropped[0]


def test_high_frequency_sigma_sees_white_noise_under_a_smooth_error():
    rng = np.random.default_rng(1)
    t = np.arange(40000) * DT
    smooth = 5e-6 * np.sin(2 * np.pi * 0.7 * t) + 1e-6 * t
    sigma = 20e-9
    estimate = high_frequency_sigma(t, smooth + rng.normal(0, sigma, t.size), DT)
    assert estimate == pytest.approx(sigma, rel=0.05)


def test_floors_without_standstill_come_from_the_high_frequency_residual():
    rng = np.random.default_rng(2)
    n = 20000
    res = residuals(
        1e-6 * np.sin(np.arange(n) * 1e-3) + rng.normal(0, 3e-8, n),
        rng.normal(0, 4e-3, n),
        regime=CONSTANT_VELOCITY,
    )
    floors = noise_floors(res, DT, resolution=0.0)
    assert floors.sigma_position_m == pytest.approx(3e-8, rel=0.08)
    assert floors.sigma_current == pytest.approx(4e-3, rel=0.08)
    assert "high-frequency" in floors.position_source


def test_an_encoder_grid_bounds_the_position_floor_from_below():
    res = residuals(np.zeros(5000), np.full(5000, 1e-3), regime=CONSTANT_VELOCITY)
    floors = noise_floors(res, DT, resolution=1e-6)
    assert floors.sigma_position_m == pytest.approx(1e-6 / np.sqrt(12))
    assert "quantisation" in floors.position_source


def _twin_and_run(extra_error: float, seed: int) -> tuple[MeasuredRun, RunRecord]:
    """A replay and a 'measured' run = replay + white noise (+ a scaled tracking error)."""
    rng = np.random.default_rng(seed)
    t = np.arange(20000) * DT
    x_ref = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    error = 2e-7 * np.sin(2 * np.pi * 1.0 * t) ** 3
    current = 0.3 * np.cos(2 * np.pi * 0.5 * t) ** 3
    record = RunRecord.from_columns({"t": t, "x": x_ref - error, "current": current})
    run = MeasuredRun.from_signals(
        "run.csv",
        {
            "t": t,
            "x_ref": x_ref,
            "x": x_ref - error * (1 + extra_error) + rng.normal(0, 3e-8, t.size),
            "current": current + rng.normal(0, 5e-3, t.size),
        },
    )
    return run, record


def test_noise_alone_is_not_a_metric_gap():
    """White noise raises ITAE and IAU of the measured run; the comparison accounts for it."""
    floors = Floors(3e-8, 5e-3, "given", "given")
    settings = DiagnosisSettings()
    for seed in range(4):
        run, record = _twin_and_run(0.0, seed)
        comparison = compare_metrics(run, record, floors, settings)
        assert comparison.off == [], comparison
        naive = abs(
            noise_module.run_metrics(run.t, run.x_ref - run.x, run.current)["ITAE"]
            / noise_module.run_metrics(run.t, run.x_ref - record["x"], run.current)["ITAE"]
            - 1
        )
        assert naive > settings.significance_metric  # what a comparison without noise says


def test_a_real_change_of_the_tracking_error_is_a_metric_gap():
    floors = Floors(3e-8, 5e-3, "given", "given")
    run, record = _twin_and_run(0.4, 0)
    comparison = compare_metrics(run, record, floors, DiagnosisSettings())
    assert "E_pk_um" in comparison.off and "ITAE" in comparison.off


def test_a_plant_without_a_noise_model_gets_no_noise_parameters():
    rng = np.random.default_rng(3)
    t = np.arange(8000) * DT
    position = 1e-7 * np.sin(2 * np.pi * 60.0 * t) + rng.normal(0, 2e-9, t.size)
    model = identify_noise(residuals(position, np.zeros_like(t)), DT, {"mass": (0, 1)}, {"mass": 1})
    assert model.plant_parameters == {} and model.harmonics == []
