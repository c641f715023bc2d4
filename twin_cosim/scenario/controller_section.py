"""The ``controller`` section of a scenario (or of one axis): the tuned parameters and the
settings.

Layout::

    controller:
      parameters: {Kp_pos: 66.667, ...}      # the six tuned parameters, or the name of a set of
                                             # the paper's Table 3 (ft, ga, ce, sa); default: ft
      settings: {current_limit: 20.0, ...}   # twin_cosim.scenario.settings_section

The settings start from the plant's drive facts (its model card at its parameter values); the
``settings`` given win over them.
"""

from __future__ import annotations

from typing import Any

from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.scenario.plant_section import PlantSection, drive_facts
from twin_cosim.scenario.settings_section import controller_settings
from twin_cosim.scenario.tuned_section import tuned_section
from twin_cosim.schema import Checker


def controller_section(
    check: Checker, plant: PlantSection, data: Any
) -> tuple[TunedParameters, ControllerSettings]:
    """The tuned parameters and the settings of a ``controller`` section for ``plant``."""
    control = check.mapping(data, "controller", {"parameters", "settings"})
    tuned = tuned_section(control.get("parameters", "ft"), check.where("controller.parameters"))
    settings = controller_settings(check, drive_facts(check, plant), control.get("settings"))
    return tuned, settings
