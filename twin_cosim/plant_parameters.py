"""Plant parameter files (``plant.yaml``): a calibrated plant that any scenario can take.

``twin diagnose --out DIR`` writes ``DIR/plant.yaml``; ``--plant-parameters FILE`` on
``simulate``, ``optimize`` and ``compare`` (or ``plant: {parameters_file: FILE}`` in a scenario)
applies it, so that one excitation run calibrates the twin for every production trajectory::

    model: drive2mass                     # the plant model (folder of models/)
    parameters:                           # FMU parameters, SI units (models/<model>/variables.yaml)
      stribeck_friction: 0.21             # N.m
      backlash: 1.93e-05                  # m
    provenance:                           # where each value came from
      stribeck_friction: {source: "accepted effect stribeck (step 1)", holdout_reduction: 0.61}
    created_by: {command: "twin diagnose ...", version: 0.1.0, measured: [...], holdout: ...}

Reading checks the model, that every name is a parameter of the model's variable table, and that
every value is finite and inside the table's range; errors name the file and the key.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from fmu_build.build import DEFAULT_MODEL, MODELS_DIR, available_models
from fmu_build.variable_table import Variable, VariableTableError, load_variable_table
from twin_cosim.plant_facts import model_start_values

if TYPE_CHECKING:
    from twin_cosim.scenario import Scenario

TOP_KEYS = {"model", "parameters", "provenance", "created_by"}
NOISE_SOURCE = "noise harmonics identified at standstill by twin diagnose"
CALIBRATION_SOURCE = (
    "calibration correction of twin diagnose: the best correction within the calibration "
    "tolerance of what the accepted effects leave on the held-out runs (linearised)"
)


class PlantParametersError(ValueError):
    """A plant parameter file is invalid; the message names the file, the key and what was
    expected."""


@dataclass(frozen=True)
class PlantParameters:
    """A calibrated plant: FMU parameter values with their origin.

    Attributes
    ----------
    model : str
        Plant model name (a folder of ``models/``).
    parameters : dict
        FMU parameter values by name, in the SI units of the model's variable table.
    provenance : dict
        Per parameter name, a mapping with at least ``source`` (text).
    created_by : dict
        What made the file (command, version, measured and held-out runs).
    source : Path or None
        The file it was read from.
    """

    model: str
    parameters: dict[str, float]
    provenance: dict[str, dict[str, Any]] = field(default_factory=dict)
    created_by: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None

    def as_dict(self) -> dict[str, Any]:
        """The file's content (YAML-ready)."""
        return {
            "model": self.model,
            "parameters": dict(self.parameters),
            "provenance": self.provenance,
            "created_by": self.created_by,
        }


def model_parameters(model: str) -> dict[str, Variable]:
    """The parameters of a model's variable table by name.

    Raises
    ------
    PlantParametersError
        When the model is not one of ``models/``.
    """
    if model not in available_models():
        raise PlantParametersError(
            f"unknown plant model {model!r}: expected one of {available_models()}"
        )
    try:
        table = load_variable_table(
            MODELS_DIR / model / "variables.yaml", MODELS_DIR / "common" / "units.yaml"
        )
    except VariableTableError as exc:
        raise PlantParametersError(str(exc)) from exc
    return {v.name: v for v in table.variables if v.causality == "parameter"}


def check_values(
    values: Mapping[str, Any], model: str, where: str, key: str = "parameters"
) -> dict[str, float]:
    """Check parameter values against the model's variable table; returns them as floats.

    Parameters
    ----------
    values
        Parameter name -> value.
    model
        Plant model name.
    where
        The file named in errors.
    key
        The key path named in errors.
    """
    try:
        known = model_parameters(model)
    except PlantParametersError as exc:
        raise PlantParametersError(f"{where}: model: {exc}") from exc
    checked = {}
    for name, value in values.items():
        at = f"{where}: {key}.{name}"
        variable = known.get(str(name))
        if variable is None:
            raise PlantParametersError(
                f"{at}: not a parameter of model {model!r}; see models/{model}/variables.yaml"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise PlantParametersError(f"{at}: expected a number in {variable.unit}, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise PlantParametersError(f"{at}: expected a finite number, got {value!r}")
        if variable.type == "Integer" and value != int(value):
            raise PlantParametersError(f"{at}: expected an integer, got {value!r}")
        low = variable.min if variable.min is not None else -math.inf
        high = variable.max if variable.max is not None else math.inf
        if not low <= value <= high or (variable.positive and value <= 0):
            limits = f"[{low:g}, {high:g}]" + (", > 0" if variable.positive else "")
            raise PlantParametersError(
                f"{at}: {value!r} {variable.unit} outside the model's range {limits}"
            )
        checked[str(name)] = value
    return checked


def read_plant_parameters(path: Path | str, model: str | None = None) -> PlantParameters:
    """Read and check a plant parameter file.

    Parameters
    ----------
    path
        The ``plant.yaml`` file.
    model
        The plant model it must be for (e.g. the scenario's); any when None.

    Raises
    ------
    PlantParametersError
        Naming the file and the key on malformed YAML, unknown keys or parameter names,
        non-finite or out-of-range values, or a model other than ``model``.
    """
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except FileNotFoundError as exc:
        raise PlantParametersError(f"{path}: file not found") from exc
    except yaml.YAMLError as exc:
        raise PlantParametersError(f"{path}: malformed YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise PlantParametersError(f"{path}: expected a mapping with keys {sorted(TOP_KEYS)}")
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise PlantParametersError(f"{path}: unknown key(s) {unknown}; allowed: {sorted(TOP_KEYS)}")
    found = data.get("model")
    if not isinstance(found, str):
        raise PlantParametersError(f"{path}: model: expected a plant model name, got {found!r}")
    if found not in available_models():
        raise PlantParametersError(
            f"{path}: model: unknown plant model {found!r}: expected one of {available_models()}"
        )
    if model is not None and found != model:
        raise PlantParametersError(
            f"{path}: model: the file is for plant model {found!r}, the scenario's plant is "
            f"{model!r}"
        )
    values = data.get("parameters")
    if not isinstance(values, dict):
        raise PlantParametersError(f"{path}: parameters: expected a mapping name -> value")
    provenance = data.get("provenance") or {}
    if not isinstance(provenance, dict) or not all(
        isinstance(v, dict) and "source" in v for v in provenance.values()
    ):
        raise PlantParametersError(
            f"{path}: provenance: expected a mapping name -> {{source: text, ...}}"
        )
    stray = sorted(set(provenance) - set(values))
    if stray:
        raise PlantParametersError(f"{path}: provenance: names without a parameter value {stray}")
    created_by = data.get("created_by") or {}
    if not isinstance(created_by, dict):
        raise PlantParametersError(f"{path}: created_by: expected a mapping")
    return PlantParameters(
        found, check_values(values, found, str(path)), provenance, created_by, path
    )


def write_plant_parameters(path: Path | str, plant: PlantParameters) -> Path:
    """Write a plant parameter file (values are checked first; floats round-trip exactly)."""
    check_values(plant.parameters, plant.model, str(path))
    path = Path(path)
    path.write_text(yaml.safe_dump(plant.as_dict(), sort_keys=False, width=100))
    return path


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
        held-out figures), ``noise.plant_parameters``, ``rounds`` (the last one's
        ``calibration.coefficients``: the correction of each calibrated parameter in units of
        the tolerance) and ``thresholds.calibration_tolerance``.
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
    rounds = summary.get("rounds") or []
    if rounds and not rounds[-1].get("accepted"):
        tolerance = float(summary["thresholds"]["calibration_tolerance"])
        base = {**model_start_values(model), **(nominal or {}), **parameters}
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


def fmu_model(path: Path | str | None) -> str:
    """The plant model of an FMU (its modelIdentifier); the default model's when None."""
    if path is None:
        return DEFAULT_MODEL
    from fmpy import read_model_description

    try:
        return read_model_description(str(path)).coSimulation.modelIdentifier
    except Exception as exc:  # noqa: BLE001 - fmpy raises several kinds on a bad file
        raise PlantParametersError(
            f"{path}: cannot read the FMU's model description: {exc}"
        ) from exc


def with_plant_parameters(
    scenario: Scenario, path: Path | str | None, fmu: Path | str | None = None
) -> Scenario:
    """The scenario with a plant parameter file's values on top of its own plant parameters.

    The command-line file wins over the scenario's ``plant.parameters`` (and over its
    ``plant.parameters_file``); ``fmu`` is the plant actually used (``--plant``), whose model
    must be the file's. Returns the scenario unchanged when ``path`` is None.
    """
    if path is None:
        return scenario
    plant = read_plant_parameters(path, fmu_model(fmu if fmu is not None else scenario.fmu))
    return dataclasses.replace(
        scenario,
        plant_parameters={**scenario.plant_parameters, **plant.parameters},
        plant_parameters_file=Path(path),
    )


def _relocated(value: Any, source_dir: Path, target_dir: Path) -> str:
    """A path relative to ``source_dir``, re-expressed relative to ``target_dir``."""
    import os

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
    from twin_cosim.scenario import load_yaml

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
