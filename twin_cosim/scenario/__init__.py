"""Scenarios: one YAML file per run set-up (plant, controller, reference, run, optimize and
diagnose sections), loaded and checked once into a typed :class:`Scenario`.

- :mod:`~twin_cosim.scenario.loader`: the file, its sections, :func:`load_scenario`;
- :mod:`~twin_cosim.scenario.plant_section`: the plant, the precedence of plant parameters
  (model start values < scenario < plant.yaml < command line), the plant facts, the mismatch
  warning;
- :mod:`~twin_cosim.scenario.plant_file`: ``plant.yaml`` files;
- :mod:`~twin_cosim.scenario.reference_section`: segments, CSV and measured references;
- :mod:`~twin_cosim.scenario.tuned_section`: the six tuned parameters and ``--params``;
- :mod:`~twin_cosim.scenario.resolved`: the :class:`Scenario` value, :func:`for_measured_run`;
- :mod:`~twin_cosim.scenario.shipped`: shipped scenarios by name;
- :mod:`~twin_cosim.scenario.controller_section`: the ``controller`` section (also per axis);
- :mod:`~twin_cosim.scenario.machine`, :mod:`~twin_cosim.scenario.axes_section`,
  :mod:`~twin_cosim.scenario.machine_loader`: a machine of several axes (``axes:``),
  :func:`load_machine`.

The YAML loader and checker shared with every other input file are :mod:`twin_cosim.schema`.
"""

from twin_cosim.scenario.loader import load_scenario, resolve_scenario
from twin_cosim.scenario.machine import AxisLimits, AxisSetup, MachineScenario
from twin_cosim.scenario.machine_loader import is_machine_scenario, load_machine
from twin_cosim.scenario.plant_section import plant_mismatch, with_plant_parameters
from twin_cosim.scenario.resolved import Scenario, for_measured_run
from twin_cosim.scenario.shipped import find_scenario
from twin_cosim.scenario.tuned_section import load_axes_parameters, load_tuned_parameters
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
    "load_tuned_parameters",
    "plant_mismatch",
    "resolve_scenario",
    "with_plant_parameters",
]
