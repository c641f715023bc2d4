"""Replays of a short case for the tests of the replay workers and their pool."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.context import variable_ranges
from twin_cosim.gap.which.replay import TRAINING_CACHE_BYTES, ReplaySpec, TrainingData, cut
from twin_cosim.plant import Plant
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[4]
STRIBECK_SET = {"stribeck_friction": 0.2, "stribeck_speed": 0.4}  # N.m, rad/s


@pytest.fixture()
def small_spec(fmu_path: Path) -> Callable[..., ReplaySpec]:
    """``small_spec(cache_bytes)``: replays of the first second of scenarios/diagnosis.yaml
    (0.5 s trained on, the whole second judged: a time split), its "measurement" the twin with
    Stribeck friction; ``cache_bytes`` of training residuals kept by a worker."""
    scenario = cut(load_scenario(ROOT / "scenarios" / "diagnosis.yaml"), 1.0)
    with Plant(fmu_path) as plant:
        ranges = variable_ranges(plant)
        nominal = {**plant.start_values(), **scenario.plant_parameters}
        measured = run_scenario(plant, scenario, plant_overrides=STRIBECK_SET)
    train = measured["t"] <= 0.5
    training = TrainingData(
        [measured["t"][train]],
        [measured["x"][train]],
        [measured["current"][train]],
        [0],
        20e-9,  # m
        5e-3,  # A
        0.5,  # s
    )

    def spec(cache_bytes: int = TRAINING_CACHE_BYTES) -> ReplaySpec:
        return ReplaySpec(
            [scenario],
            [scenario],
            str(fmu_path),
            nominal,
            training,
            "drive2mass",
            ranges,
            cache_bytes,
        )

    return spec
