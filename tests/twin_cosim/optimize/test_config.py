"""The optimize section: defaults, normalisation, and named errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin_cosim.controller_set import TABLE3
from twin_cosim.optimize.config import DEFAULT_BOUNDS, load_config, within_bounds
from twin_cosim.scenario import ScenarioError, load_scenario

BASE = (
    "reference:\n  segments:\n    - dwell: 0.1\n"
    "    - move: {to: 0.001, velocity: 0.01, acceleration: 0.1}\n"
)
REFERENCE1 = Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml"


def config_of(tmp_path, optimize: str):
    path = tmp_path / "s.yaml"
    path.write_text(BASE + optimize)
    return load_config(load_scenario(path))


def test_defaults_hold_every_table3_set():
    config = load_config(load_scenario(REFERENCE1))
    assert config.iau_cap == 1.05
    assert all(within_bounds(config, tuned.as_array()) for tuned in TABLE3.values())
    assert config.window == (0.0, None)


def test_unit_mapping_round_trips(tmp_path):
    config = config_of(tmp_path, "optimize:\n  bounds: {Kp_pos: [10, 110]}\n")
    x = TABLE3["ft"].as_array()
    np.testing.assert_allclose(config.from_unit(config.to_unit(x)), x)
    assert config.from_unit(np.zeros(6))[0] == 10.0
    assert config.from_unit(np.ones(6))[1] == DEFAULT_BOUNDS["Kp_vel"][1]


@pytest.mark.parametrize(
    ("optimize", "message"),
    [
        ("optimize:\n  budget: 3\n", r"optimize: unknown key\(s\) \['budget'\]"),
        ("optimize:\n  bounds: {Kp: [1, 2]}\n", "unknown parameter 'Kp'"),
        ("optimize:\n  bounds: {Kp_pos: [5, 1]}\n", "expected low < high"),
        ("optimize:\n  bounds: {Kp_pos: [0, 1]}\n", "lower bound 0.0 allows invalid values"),
        ("optimize:\n  iau_cap: -1\n", "optimize.iau_cap: expected a number > 0"),
        ("optimize:\n  penalty_um: .inf\n", "optimize.penalty_um: expected a finite number"),
        ("optimize:\n  methods: {ce: 3}\n", "optimize.methods: expected a mapping"),
    ],
)
def test_mistakes_are_named(tmp_path, optimize, message):
    with pytest.raises(ScenarioError, match=message) as info:
        config_of(tmp_path, optimize)
    assert "s.yaml" in str(info.value)


def test_plant_samples_draw_within_the_intervals_and_the_tolerance():
    from twin_cosim.optimize.config import UncertaintySet, relative_ranges

    ranges = relative_ranges(
        {"backlash": (18e-6, 24e-6), "coulomb_asymmetry": (-0.01, 0.01)},
        {"backlash": 20e-6, "coulomb_asymmetry": 0.0},
    )
    assert ranges == {"backlash": pytest.approx((0.9, 1.2))}  # no relative range around 0
    samples = UncertaintySet(0.03, 200, 5, ("backlash", "torque_constant"), ranges).factors()
    assert samples[0] == {}
    backlash = np.array([s["backlash"] for s in samples[1:]])
    torque = np.array([s["torque_constant"] for s in samples[1:]])
    assert 0.9 <= backlash.min() < 0.92 and 1.18 < backlash.max() <= 1.2
    assert 0.97 <= torque.min() < 0.975 and 1.025 < torque.max() <= 1.03
    assert UncertaintySet(0.03, 200, 5, ("backlash",), ranges).factors() != samples
