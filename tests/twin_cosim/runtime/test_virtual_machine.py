"""The virtual machine: the calibration error drawn once, each drift's steps per window."""

from __future__ import annotations

import pytest
from runtime_cases import cycle, machine

from twin_cosim.gap.synth import parse_effect
from twin_cosim.runtime.virtual_machine import Drift, draw_machine, parse_drift


def test_drifts_grow_by_their_rate_from_their_first_window(tmp_path) -> None:
    scenario = cycle(tmp_path)
    vm = machine(
        scenario,
        [Drift("coulomb_change", "delta_coulomb", 0.01), Drift("plant", "backlash", 1e-6)],
        start=3,
    )
    base = vm.base
    for window, steps in ((0, 0), (2, 0), (3, 1), (7, 5)):
        parameters = vm.parameters_at(window)
        assert parameters["coulomb_friction"] == pytest.approx(
            base["coulomb_friction"] + 0.01 * steps
        )
        assert parameters["backlash"] == pytest.approx(base["backlash"] + 1e-6 * steps)
    assert 0.98 <= vm.factors["torque_constant"] <= 1.02


def test_a_drift_of_an_effect_switched_on_starts_from_its_values(tmp_path) -> None:
    scenario = cycle(tmp_path)
    vm = draw_machine(
        scenario,
        str(scenario.plant_fmu()),
        [parse_effect("torque_ripple:cos_part=0.02,sin_part=0.0")],
        [parse_drift("torque_ripple:cos_part=0.01")],
    )
    assert vm.parameters_at(0)["ripple_amplitude"] == pytest.approx(0.03)
    assert vm.parameters_at(2)["ripple_amplitude"] == pytest.approx(0.05)


def test_bad_drifts_are_refused_naming_what_was_expected(tmp_path) -> None:
    with pytest.raises(ValueError, match="one param=RATE_PER_WINDOW"):
        parse_drift("coulomb_change:delta_coulomb=1,x=2")
    with pytest.raises(ValueError, match="unknown effect"):
        parse_drift("wear:rate=1")
    with pytest.raises(ValueError, match="no parameter 'speed'"):
        machine(cycle(tmp_path), [Drift("coulomb_change", "speed", 0.1)])
