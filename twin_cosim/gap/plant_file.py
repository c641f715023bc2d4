"""The plant file a diagnosis leaves: ``plant.yaml`` and the scenario calibrated with it.

``plant.yaml`` holds the noise, the accepted effects and the calibration correction of a
diagnosis (:func:`twin_cosim.plant_parameters.from_diagnosis`), with the command that made it;
``calibrated.yaml`` is the diagnosed scenario pointing at it, ready for ``twin simulate`` or
``twin optimize``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from twin_cosim.plant_parameters import (
    calibrated_scenario,
    fmu_model,
    from_diagnosis,
    write_plant_parameters,
)
from twin_cosim.scenario import Scenario
from twin_cosim.versions import versions


def write_calibration(
    scenario: Scenario,
    summary: dict[str, Any],
    out: Path,
    command: str,
    fmu: Path | str | None = None,
) -> dict[str, str]:
    """Write ``out/plant.yaml`` and ``out/calibrated.yaml`` of a diagnosis.

    Parameters
    ----------
    scenario
        The diagnosed scenario (its plant parameters are the nominal values).
    summary
        The diagnosis summary (:meth:`twin_cosim.gap.diagnosis.Diagnosis.summary`).
    out
        The report folder.
    command
        The command that made the diagnosis, kept in ``plant.yaml``.
    fmu
        The plant diagnosed (``--plant``); none: the scenario's.

    Returns
    -------
    dict
        Paths of the files written: ``plant`` and ``calibrated``.
    """
    made_by = {"command": command, "version": versions()["twin-cosim"]}
    model = fmu_model(fmu or scenario.fmu)
    plant = from_diagnosis(summary, model, made_by, scenario.plant_parameters)
    plant_file = write_plant_parameters(out / "plant.yaml", plant)
    calibrated = calibrated_scenario(scenario.source, plant, out / "calibrated.yaml")
    return {"plant": str(plant_file), "calibrated": str(calibrated)}
