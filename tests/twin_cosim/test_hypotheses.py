"""The effect library's mappings to FMU parameters, against their formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.plant_model import plant_model

LIBRARY = plant_model("drive2mass").hypotheses
BY_NAME = {h.name: h for h in LIBRARY}

NOMINAL = {
    "coulomb_friction": 0.625,
    "backlash": 12.2e-6,
    "motor_inertia": 2.9e-4,
    "load_inertia": 4.2e-4,
    "resonance_frequency": 70.0,
}
CONTEXT = {"motor_order": 6.0, "screw_order": 1.0, "position_resolution": 0.0}


def test_library_names_and_units():
    assert len(LIBRARY) == len(BY_NAME) > 0  # names are unique
    for hypothesis in LIBRARY:
        assert 1 <= len(hypothesis.parameters) <= 4
        u = hypothesis.initial_unit()
        assert np.all((u >= 0) & (u <= 1))


@pytest.mark.parametrize("name", ["pitch_error", "torque_ripple"])
def test_cos_sin_parts_map_to_amplitude_and_phase(name):
    hypothesis = BY_NAME[name]
    values = np.array([0.0, 3e-6, -4e-6]) if name == "pitch_error" else np.array([3.0, -4.0])
    params = hypothesis.to_plant(values, NOMINAL, CONTEXT)
    prefix = "pitch_error" if name == "pitch_error" else "ripple"
    amplitude = params[f"{prefix}_amplitude{'_1' if name == 'pitch_error' else ''}"]
    phase = params[f"{prefix}_phase{'_1' if name == 'pitch_error' else ''}"]
    for u in np.linspace(0, 2 * math.pi, 7):
        fitted = values[-2] * math.cos(u) + values[-1] * math.sin(u)
        assert amplitude * math.sin(u + phase) == pytest.approx(fitted, abs=1e-12)


def test_inertia_change_keeps_the_coupling_stiffness():
    params = BY_NAME["inertia_change"].to_plant(np.array([0.21]), NOMINAL, CONTEXT)
    stiffness = params["load_inertia"] * (2 * math.pi * params["resonance_frequency"]) ** 2
    assert stiffness == pytest.approx(NOMINAL["load_inertia"] * (2 * math.pi * 70.0) ** 2)
    assert params["motor_inertia"] == pytest.approx(2.9e-4 * 1.21)


def test_calibration_sizes():
    assert BY_NAME["stiffness_change"].relative_size(np.array([0.21]), NOMINAL) == pytest.approx(
        0.1
    )
    assert BY_NAME["backlash_change"].relative_size(np.array([1.22e-6]), NOMINAL) == pytest.approx(
        0.1
    )
    assert BY_NAME["stribeck"].relative_size is None
