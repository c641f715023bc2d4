"""What the drive assumes about the plant, taken from the plant model's own parameters.

The controller's feedforward and compensation need the carriage travel per motor radian, the
inertia, the torque constant and the friction level. They are not written a second time in the
controller: they come from the plant model's parameters (the start values in its variable table
``models/<model>/variables.yaml`` or in an FMU's ``modelDescription.xml``), with the scenario's
``plant.parameters`` on top. A scenario's ``controller.settings`` may still set any of them (a
drive commissioned with other values than the plant's).

Two kinds of plant are known by their parameter names (all motor-referred in the result):

- rotary (drive2mass): ``spindle_constant`` [m/rad] and ``gear_ratio`` [1] give the travel
  spindle_constant / gear_ratio [m/rad]; ``motor_inertia`` + ``load_inertia`` [kg.m2];
  ``torque_constant`` [N.m/A]; ``coulomb_friction`` [N.m];
- linear (emps): ``lead_per_rad`` [m/rad] is the travel; ``mass`` [kg] gives the inertia
  mass lead^2 [kg.m2], ``drive_gain`` [N/V] the torque constant drive_gain lead [N.m/V] and
  ``coulomb_friction`` [N] the friction torque coulomb_friction lead [N.m], so that the
  feedforward J a / (travel K_t) = M a / drive_gain is the force over the drive gain.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

DRIVE_FACTS = ("travel_per_rad", "inertia", "torque_constant", "friction_torque")


def drive_facts(parameters: Mapping[str, float]) -> dict[str, float]:
    """The drive's plant facts (names of :data:`DRIVE_FACTS`) from plant parameter values.

    Parameters
    ----------
    parameters
        Plant parameter values by name (start values with the scenario's values on top).

    Returns
    -------
    dict
        The facts the parameters determine: travel_per_rad [m/rad], inertia [kg.m2],
        torque_constant [N.m/A, or N.m/V], friction_torque [N.m]; a plant of unknown kind gives
        an empty dict.
    """
    p = parameters
    if "lead_per_rad" in p:
        lead = p["lead_per_rad"]
        facts = {"travel_per_rad": lead}
        if "mass" in p:
            facts["inertia"] = p["mass"] * lead**2
        if "drive_gain" in p:
            facts["torque_constant"] = p["drive_gain"] * lead
        if "coulomb_friction" in p:
            facts["friction_torque"] = p["coulomb_friction"] * lead
        return facts
    facts = {}
    if "spindle_constant" in p and "gear_ratio" in p:
        facts["travel_per_rad"] = p["spindle_constant"] / p["gear_ratio"]
    if "motor_inertia" in p and "load_inertia" in p:
        facts["inertia"] = p["motor_inertia"] + p["load_inertia"]
    if "torque_constant" in p:
        facts["torque_constant"] = p["torque_constant"]
    if "coulomb_friction" in p:
        facts["friction_torque"] = p["coulomb_friction"]
    return facts


def model_start_values(model: str) -> dict[str, float]:
    """Start values of the parameters in the variable table of ``models/<model>``."""
    from fmu_build.build import COMMON_DIR, MODELS_DIR
    from fmu_build.variable_table import load_variable_table

    table = load_variable_table(MODELS_DIR / model / "variables.yaml", COMMON_DIR / "units.yaml")
    return {
        v.name: float(v.start)
        for v in table.variables
        if v.causality == "parameter" and v.start is not None
    }


def model_variable_names(model: str) -> set[str]:
    """Names of all variables in the variable table of ``models/<model>``."""
    from fmu_build.build import COMMON_DIR, MODELS_DIR
    from fmu_build.variable_table import load_variable_table

    table = load_variable_table(MODELS_DIR / model / "variables.yaml", COMMON_DIR / "units.yaml")
    return {v.name for v in table.variables}


def fmu_identity(fmu: Path) -> tuple[str, set[str], dict[str, float]]:
    """Model identifier, variable names and parameter start values of an FMU file."""
    from fmpy import read_model_description

    description = read_model_description(str(fmu), validate=False)
    identifier = (
        description.coSimulation.modelIdentifier
        if description.coSimulation is not None
        else description.modelName
    )
    starts = {
        v.name: float(v.start)
        for v in description.modelVariables
        if v.causality == "parameter" and v.start is not None
    }
    return identifier, {v.name for v in description.modelVariables}, starts
