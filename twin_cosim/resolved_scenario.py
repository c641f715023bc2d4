"""A scenario file resolved into the typed value every run uses: the one place that does it.

Loading checks the file and resolves what it names (reference, measured run, plant facts); a
plant parameter file (``plant.yaml`` of ``twin diagnose``) then puts its values on top of the
scenario's plant parameters. A campaign resolves its scenarios once, in the parent, and sends
the values to its workers.
"""

from __future__ import annotations

from pathlib import Path

from twin_cosim.plant_parameters import with_plant_parameters
from twin_cosim.scenario import Scenario, load_scenario


def resolve_scenario(
    path: Path | str, plant_parameters: Path | str | None = None, fmu: Path | str | None = None
) -> Scenario:
    """The scenario of a file (or shipped name), with a plant parameter file applied.

    Parameters
    ----------
    path
        Scenario YAML file, or the name of a shipped scenario.
    plant_parameters
        Plant parameter file whose values win over the scenario's; none: the scenario's own.
    fmu
        The plant actually used (``--plant``), whose model the parameter file must be of;
        none: the scenario's.

    Raises
    ------
    ScenarioError
        On a malformed scenario file.
    PlantParametersError
        On a malformed plant parameter file, or one of another model than the plant's.
    """
    return with_plant_parameters(load_scenario(path), plant_parameters, fmu)
