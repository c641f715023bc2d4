"""Nothing a fit derives from data reaches the FMU outside the variable table's ranges."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.replay import bounded, clipped
from twin_cosim.gap.synth import DEFAULT_CONTEXT
from twin_cosim.plant_model import plant_model

BY_NAME = {h.name: h for h in plant_model("drive2mass").hypotheses}


def test_position_friction_at_its_fit_bounds_is_clipped_to_the_fmu_range(plant):
    """cos and sin parts at 0.9 each give an amplitude of 1.27 > the FMU's 0.99."""
    from twin_cosim.gap.context import variable_ranges

    ranges = variable_ranges(plant)
    hypothesis = BY_NAME["position_friction"]
    overrides = hypothesis.to_plant(np.array([0.9, 0.9]), {}, DEFAULT_CONTEXT)
    assert overrides["position_friction_amplitude"] == pytest.approx(np.hypot(0.9, 0.9))
    safe = clipped(overrides, ranges)
    assert safe["position_friction_amplitude"] == ranges["position_friction_amplitude"][1]
    plant.start_run(safe)  # accepted by the FMU


def test_bounds_of_fmu_parameters_come_from_the_variable_table():
    ranges = {"stribeck_friction": (0.0, 1.5), "stribeck_speed": (0.1, 100.0)}
    narrowed = bounded(BY_NAME["stribeck"], ranges)
    friction, speed = narrowed.parameters
    assert (friction.lower, friction.upper) == (0.0, 1.5)
    assert (speed.lower, speed.upper) == (0.1, 2.0)
    assert speed.lower <= speed.initial <= speed.upper
