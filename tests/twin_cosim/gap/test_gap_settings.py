"""Diagnosis settings: from the scenario and the command line, with clear errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from twin_cosim.gap.settings import settings_from
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[3]


def scenario_with(diagnose: dict):
    return dataclasses.replace(
        load_scenario(ROOT / "scenarios" / "diagnosis.yaml"), diagnose=diagnose
    )


def test_defaults_and_overrides():
    settings = settings_from(scenario_with({"acceptance_level": 0.05}), split=0.6, max_effects=2)
    assert (settings.acceptance_level, settings.split, settings.max_effects) == (0.05, 0.6, 2)


@pytest.mark.parametrize(
    ("diagnose", "split", "max_effects", "message"),
    [
        ({"nope": 1}, None, None, r"diagnose: unknown key\(s\) \['nope'\]"),
        ({"max_effects": 1.5}, None, None, "diagnose.max_effects: expected a whole number"),
        ({"acceptance_level": float("nan")}, None, None, "expected a finite number"),
        ({"significance_level": 0.0}, None, None, r"significance_level: expected a one-sided"),
        ({"acceptance_level": 0.5}, None, None, r"acceptance_level: expected a one-sided"),
        ({}, None, -1, "--max-effects: expected a whole number >= 1, got -1"),
        ({}, 0.95, None, r"split: expected a fraction in \[0.1, 0.9\]"),
    ],
)
def test_bad_settings_are_named(diagnose, split, max_effects, message):
    with pytest.raises(ValueError, match=message):
        settings_from(scenario_with(diagnose), split, max_effects)
