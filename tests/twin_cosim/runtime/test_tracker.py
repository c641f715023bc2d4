"""The drift tracker on the virtual machine: calibration to the noise floor, the linearised
update against known steps of an effect, no alarm while stationary, the drifting effect named."""

from __future__ import annotations

import pytest
from runtime_cases import cycle, machine

from twin_cosim.plant import Plant
from twin_cosim.runtime.tracker import SMALLEST_RELEVANT_CHANGE, Tracker, tracked_parameters
from twin_cosim.runtime.virtual_machine import Drift


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
