"""Scenarios: one YAML file per run set-up (plant, controller, reference, run, optimize and
diagnose sections), loaded and checked once into a typed :class:`Scenario`.

- :mod:`~twin_cosim.scenario.loader`: the file, its sections, :func:`load_scenario`; shipped
  scenarios by name (:func:`find_scenario`);
- :mod:`~twin_cosim.scenario.plant_parameters`: the plant, the precedence of plant parameters
  (model start values < scenario < plant.yaml < command line), the plant facts, the mismatch
  warning;
- :mod:`~twin_cosim.scenario.plant_parameters`: ``plant.yaml`` files;
- :mod:`~twin_cosim.scenario.reference_section`: segments, CSV and measured references;
- :mod:`~twin_cosim.scenario.controller_section`: the ``controller`` section (the six tuned
  parameters, ``controller.settings``, current filters; also per axis) and controller sets
  (``--params``, ``--start``, also per axis);
- :mod:`~twin_cosim.scenario.resolved`: the :class:`Scenario` value, :func:`for_measured_run`,
  :func:`with_controller_set`;
- :mod:`~twin_cosim.scenario.machine`: a machine of several axes (``axes:``), its
  :class:`MachineScenario` and :func:`load_machine`.

The YAML loader and checker shared with every other input file are :mod:`twin_cosim.schema`.
"""

from twin_cosim.scenario.controller_section import load_axes_parameters, load_controller_set
from twin_cosim.scenario.loader import find_scenario, load_scenario, resolve_scenario
from twin_cosim.scenario.machine import (
    AxisLimits,
    AxisSetup,
    MachineScenario,
    is_machine_scenario,
    load_machine,
)
from twin_cosim.scenario.plant_parameters import plant_mismatch, with_plant_parameters
from twin_cosim.scenario.resolved import Scenario, for_measured_run, with_controller_set
from twin_cosim.schema import ScenarioError

__all__ = [
    "AxisLimits",
    "AxisSetup",
    "MachineScenario",
    "Scenario",
    "ScenarioError",
    "find_scenario",
    "for_measured_run",
    "is_machine_scenario",
    "load_axes_parameters",
    "load_machine",
    "load_scenario",
    "load_controller_set",
    "plant_mismatch",
    "resolve_scenario",
    "with_controller_set",
    "with_plant_parameters",
]
