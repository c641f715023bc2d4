"""The ``controller`` section of a scenario (or of one axis): tuned parameters and settings.

Layout::

    controller:
      parameters: {Kp_pos: 66.667, ...}      # the six tuned parameters, or the name of a set of
                                             # the paper's Table 3 (ft, ga, ce, sa); default: ft
      settings: {current_limit: 20.0, ...}   # see twin_cosim.controller.ControllerSettings

The settings start from the plant's drive facts (its model card at its parameter values); the
``settings`` given win over them.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.plant_model import DRIVE_FACTS
from twin_cosim.scenario.plant_section import PlantSection, drive_facts
from twin_cosim.scenario.tuned_section import tuned_section
from twin_cosim.schema import Checker, ScenarioError


def controller_section(
    check: Checker, plant: PlantSection, data: Any
) -> tuple[TunedParameters, ControllerSettings]:
    """The tuned parameters and the settings of a ``controller`` section for ``plant``."""
    control = check.mapping(data, "controller", {"parameters", "settings"})
    tuned = tuned_section(control.get("parameters", "ft"), check.where("controller.parameters"))
    return tuned, _settings(check, plant, control.get("settings"))


def _settings(check: Checker, plant: PlantSection, raw: Any) -> ControllerSettings:
    """Controller settings: the plant's drive facts, then ``controller.settings`` on top."""
    given = check.mapping(raw, "controller.settings", {f.name for f in fields(ControllerSettings)})
    facts = drive_facts(check, plant)
    try:
        return ControllerSettings(
            **{name: facts[name] for name in DRIVE_FACTS if name in facts}
            | {k: check.number(v, f"controller.settings.{k}") for k, v in given.items()}
        )
    except ValueError as exc:
        raise ScenarioError(f"{check.where('controller.settings')}: {exc}") from exc
