"""CUSUM tests: the design of the threshold against simulated run lengths, the baseline spread's
confidence bound, the change point and the rate of a ramp.

The drift tracker on the virtual machine: calibration to the noise floor, the linearised
update against known steps of an effect, no alarm while stationary, the drifting effect named.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from runtime_cases import cycle, machine

from twin_cosim.plant import Plant
from twin_cosim.runtime.tracker import (
    ALLOWANCE,
    SMALLEST_RELEVANT_CHANGE,
    Cusum,
    Tracker,
    baseline_spread,
    siegmund_arl,
    threshold_for,
    tracked_parameters,
)
from twin_cosim.runtime.virtual_machine import Drift


def test_the_threshold_inverts_siegmunds_average_run_length() -> None:
    for arl in (50.0, 1e3, 1e5):
        assert math.isclose(siegmund_arl(threshold_for(arl)), arl, rel_tol=1e-6)
    # The textbook value: k = 0.5, h = 4 gives an in-control ARL of about 336 windows.
    assert 300 < siegmund_arl(4.0, 0.5) < 400


def test_simulated_run_lengths_of_normal_increments_match_the_design() -> None:
    rng = np.random.default_rng(0)
    h = threshold_for(100.0)
    runs, length = 400, 3000
    z = rng.standard_normal((runs, length))
    s = np.zeros(runs)
    stopped = np.full(runs, length)
    for t in range(length):
        s = np.maximum(0.0, s + z[:, t] - ALLOWANCE)
        newly = (s > h) & (stopped == length)
        stopped[newly] = t + 1
    assert 80 < np.mean(stopped) < 125  # Siegmund's approximation within the sampling spread


def test_the_baseline_spread_is_raised_to_its_upper_confidence_bound() -> None:
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    from scipy.stats import chi2

    factor = math.sqrt(7 / chi2.ppf(0.1, 7))  # one-sided 90 % with 7 degrees of freedom
    assert math.isclose(baseline_spread(values), np.std(values, ddof=1) * factor)
    assert baseline_spread(np.ones(5), floor=0.25) == 0.25
    with pytest.raises(ValueError, match="at least 3"):
        baseline_spread(np.ones(2))


def test_a_ramp_is_found_with_its_start_and_rate_and_alarms_once() -> None:
    test = Cusum("friction", mean=0.0, spread=1.0, threshold=threshold_for(1e4))
    rng = np.random.default_rng(1)
    alarms = []
    for window in range(40):
        drift = 0.8 * (window - 19) if window >= 20 else 0.0
        if test.update(window, drift + 0.3 * rng.standard_normal()):
            alarms.append(window)
    assert len(alarms) == 1 and 20 <= alarms[0] <= 30
    assert test.direction == 1 and 18 <= test.since <= 21
    assert test.rate() == pytest.approx(0.8, rel=0.25)


def test_a_fall_is_found_by_a_two_sided_test_only() -> None:
    both = Cusum("a", 0.0, 1.0, 5.0)
    rise_only = Cusum("b", 0.0, 1.0, 5.0, two_sided=False)
    for window in range(10):
        both.update(window, -3.0)
        rise_only.update(window, -3.0)
    assert both.crossed is not None and both.direction == -1
    assert rise_only.crossed is None


def run(tracker: Tracker, vm, windows: range) -> list:
    alarms = []
    for w in windows:
        check, found = tracker.check(w, vm.window(w), f"window {w}")
        if tracker.ready:
            tracker.make_baseline()
        alarms += found
        yield check, alarms


def test_calibration_brings_the_gap_to_the_noise_floor_and_no_stationary_window_alarms(
    tmp_path,
) -> None:
    scenario = cycle(tmp_path)
    vm = machine(scenario)
    with Plant(scenario.plant_fmu()) as plant:
        tracker = Tracker(scenario, plant, baseline_windows=4)
        checks = list(run(tracker, vm, range(10)))
    before = [c.gap.normalised_rms for c, _ in checks[:4]]
    after = [c.gap.normalised_rms for c, _ in checks[4:]]
    assert min(before) > 1.5  # 2 % calibration error is a gap against the nominal twin
    assert max(after) < 1.1  # the calibrated twin leaves noise
    assert checks[-1][1] == []
    corrections = tracker.baseline.corrections
    factors = vm.factors  # the calibration error the machine was drawn with
    # What the data determine: the friction level over the torque constant, the backlash.
    assert (1 + corrections["coulomb_friction"]) / (1 + corrections["torque_constant"]) == (
        pytest.approx(factors["coulomb_friction"] / factors["torque_constant"], rel=5e-3)
    )


def test_a_friction_drift_is_alarmed_at_once_named_with_its_rate(tmp_path) -> None:
    scenario = cycle(tmp_path)
    rate = 0.005 * 0.625  # 0.5 % of the Coulomb level per window
    vm = machine(scenario, [Drift("coulomb_change", "delta_coulomb", rate)], start=6)
    with Plant(scenario.plant_fmu()) as plant:
        tracker = Tracker(scenario, plant, baseline_windows=4)
        *_, (check, alarms) = run(tracker, vm, range(10))
    first = alarms[0]
    assert first.effect == "coulomb_change" and 6 <= first.window <= 8
    assert first.rate == pytest.approx(rate, rel=0.1)
    values = check.values["coulomb_change.delta_coulomb"]
    assert values - tracker.baseline.tests["coulomb_change.delta_coulomb"].mean == (
        pytest.approx(4 * rate, rel=0.1)
    )


def test_an_unknown_or_scanned_effect_is_refused() -> None:
    with pytest.raises(ValueError, match="not an effect of plant model"):
        tracked_parameters("drive2mass", ("wear",))
    with pytest.raises(ValueError, match="scan"):
        tracked_parameters("drive2mass", ("dead_time",))


def test_the_smallest_relevant_change_is_a_thousandth_of_the_nominal_value() -> None:
    nominal = {"backlash": 12.2e-6, "coulomb_friction": 0.625}
    found = {
        p.key: p
        for p in tracked_parameters(
            "drive2mass", ("backlash_change", "coulomb_change", "torque_ripple"), nominal
        )
    }
    smallest = {
        k: SMALLEST_RELEVANT_CHANGE / p.relevant_per_unit
        for k, p in found.items()
        if p.relevant_per_unit
    }
    assert smallest["backlash_change.delta_backlash"] == pytest.approx(12.2e-9)
    assert smallest["coulomb_change.delta_coulomb"] == pytest.approx(0.625e-3)
    assert found["torque_ripple.cos_part"].relevant_per_unit is None  # no calibrated parameter
