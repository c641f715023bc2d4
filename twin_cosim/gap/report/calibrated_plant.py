"""The calibrated plant of a diagnosis: ``plant.yaml`` and ``calibrated.yaml`` from its summary.

:func:`from_diagnosis` turns the JSON summary of ``twin diagnose`` into a plant parameter file
(:mod:`twin_cosim.scenario.plant_file`): the identified noise harmonics, the accepted effects'
FMU parameters and the calibration correction, each with where it came from.
:func:`calibrated_scenario` folds such a file into a copy of the diagnosed scenario;
:func:`write_calibration` writes both beside a diagnosis report.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.plant_file import (
    PlantParameters,
    read_plant_parameters,
    write_plant_parameters,
)
from twin_cosim.schema import load_yaml
from twin_cosim.versions import versions

NOISE_SOURCE = "noise harmonics identified at standstill by twin diagnose"
CALIBRATION_SOURCE = (
    "calibration correction of twin diagnose: the best correction within the calibration "
    "tolerance of what the accepted effects leave on the held-out runs (linearised)"
)


def _changed(before: Mapping[str, float], after: Mapping[str, float]) -> list[str]:
    return [name for name, value in after.items() if before.get(name) != value]


def from_diagnosis(
    summary: Mapping[str, Any],
    model: str,
    created_by: Mapping[str, Any] | None = None,
    nominal: Mapping[str, float] | None = None,
) -> PlantParameters:
    """The calibrated plant of a diagnosis: noise, accepted effects and calibration correction.

    Parameters
    ----------
    summary
        The JSON summary of ``twin diagnose``: ``steps`` (accepted effects, each with its
        cumulative FMU ``plant_parameters``, ``fitted`` hypothesis, fitted ``params`` and
        held-out figures), ``final_plant_parameters`` (the kept effects' FMU parameters after
        joint refits and the backward pass, which win), ``noise.plant_parameters``, ``rounds``
        (the last one's ``calibration.coefficients``: the correction of each calibrated
        parameter in units of the tolerance) and ``thresholds.calibration_tolerance``.
    model
        The plant model the diagnosis ran on.
    created_by
        What made it (command, version, runs); ``measured`` and ``holdout`` default to the
        summary's.
    nominal
        The diagnosed scenario's plant parameters (SI units of the model's variable table), on
        top of the model's start values: what the correction multiplies.

    Notes
    -----
    A calibrated parameter p becomes p (1 + a tol), a the last round's coefficient (|a| <= 1),
    when that round accepted nothing (its residual is what the accepted effects leave); an
    accepted effect's value of p is the one corrected.
    """
    parameters: dict[str, float] = {}
    provenance: dict[str, dict[str, Any]] = {}
    noise = (summary.get("noise") or {}).get("plant_parameters") or {}
    for name, value in noise.items():
        parameters[name] = float(value)
        provenance[name] = {"source": NOISE_SOURCE}
    previous: dict[str, float] = {}
    for number, step in enumerate(summary.get("steps") or [], start=1):
        cumulative = {k: float(v) for k, v in step["plant_parameters"].items()}
        for name in _changed(previous, cumulative):
            provenance[name] = {
                "source": f"accepted effect {step['fitted']} (step {number} of twin diagnose)",
                "effect": step["effect"],
                "fitted": dict(step.get("params", {})),
                "holdout_reduction": step.get("reduction"),
                "holdout_gap_um": [
                    step.get("holdout_gap_before_um"),
                    step.get("holdout_gap_after_um"),
                ],
            }
        parameters |= cumulative
        previous = cumulative
    final = summary.get("final_plant_parameters")
    if final is not None:  # after joint refits and the backward pass
        for name in set(previous) - set(final):
            parameters.pop(name, None)
            provenance.pop(name, None)
        for name, value in final.items():
            if name in provenance and parameters.get(name) != float(value):
                provenance[name]["refitted_jointly"] = True
            parameters[name] = float(value)
    rounds = summary.get("rounds") or []
    if rounds and not rounds[-1].get("accepted"):
        tolerance = float(summary["thresholds"]["calibration_tolerance"])
        base = {**plant_model(model).start_values(), **(nominal or {}), **parameters}
        for name, a in (rounds[-1].get("calibration") or {}).get("coefficients", {}).items():
            if a != 0.0:
                parameters[name] = float(base[name] * (1.0 + a * tolerance))
                provenance[name] = {
                    "source": CALIBRATION_SOURCE,
                    "before": float(base[name]),
                    "relative_change": float(a * tolerance),
                }
    made = {"measured": summary.get("measured"), "holdout": summary.get("holdout")}
    return PlantParameters(model, parameters, provenance, {**made, **(created_by or {})})


def _relocated(value: Any, source_dir: Path, target_dir: Path) -> str:
    """A path relative to ``source_dir``, re-expressed relative to ``target_dir``."""
    path = Path(str(value))
    if path.is_absolute():
        return str(path)
    return os.path.relpath((source_dir / path).resolve(), target_dir.resolve())


def calibrated_scenario(scenario_file: Path | str, plant: PlantParameters, out: Path | str) -> Path:
    """Write ``out``: the scenario file with the calibrated values folded into plant.parameters.

    Values of a ``plant.parameters_file`` are folded in too (the file key is dropped); the
    calibrated values win. Paths the scenario names (``plant.fmu``, ``reference.csv``,
    ``reference.measured``) are rewritten relative to the new file's folder.
    """
    scenario_file, out = Path(scenario_file), Path(out)
    data = load_yaml(scenario_file)
    plant_section = dict(data.get("plant") or {})
    folded = dict(plant_section.get("parameters") or {})
    if "parameters_file" in plant_section:
        extra = read_plant_parameters(
            scenario_file.parent / str(plant_section.pop("parameters_file"))
        )
        folded = {**extra.parameters, **folded}
    plant_section["parameters"] = {**folded, **plant.parameters}
    for section, key in (("plant", "fmu"), ("reference", "csv"), ("reference", "measured")):
        body = plant_section if section == "plant" else data.get(section) or {}
        if key in body:
            body[key] = _relocated(body[key], scenario_file.parent, out.parent)
    data["plant"] = plant_section
    data["description"] = (
        f"{data.get('description', '')} Calibrated: the plant parameters of the plant.yaml "
        "beside this file folded in."
    ).strip()
    out.write_text(yaml.safe_dump(data, sort_keys=False, width=100))
    return out


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
    model = scenario.model_name(fmu)
    plant = from_diagnosis(summary, model, made_by, scenario.plant_parameters)
    plant_file = write_plant_parameters(out / "plant.yaml", plant)
    calibrated = calibrated_scenario(scenario.source, plant, out / "calibrated.yaml")
    return {"plant": str(plant_file), "calibrated": str(calibrated)}
