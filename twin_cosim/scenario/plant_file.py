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
    intervals:                            # what the diagnosis leaves uncertain: the range
      stribeck_friction: [0.19, 0.23]     # of each value, same units (robust tuning samples it)
    created_by: {command: "twin diagnose ...", version: 0.1.0, measured: [...], holdout: ...}

It is read with the scenarios' YAML loader and checker (:mod:`twin_cosim.schema`), so a value
reads the same in both (``2e-5`` is a number). Reading checks the model, that every name is a
parameter of the model's variable table, and that every value is finite and inside the table's
range, and that each interval is a pair [low, high] inside that range holding the parameter's
value; errors name the file and the key. Writing spells every value out where it stands (no
YAML anchors and aliases for a person editing the file to decode).

:func:`calibrated_scenario` folds such a file into a copy of a scenario file
(``calibrated.yaml`` beside a diagnosis' ``plant.yaml``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fmu_build.variable_table import Variable
from twin_cosim.plant_model import PlantModelError, plant_model
from twin_cosim.schema import Checker, ScenarioError, load_yaml

TOP_KEYS = {"model", "parameters", "provenance", "intervals", "created_by"}


class _PlainDumper(yaml.SafeDumper):
    """YAML written out in full: an object met twice is written twice, never as an anchor and
    an alias (``&id001``, ``*id001``)."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


def dump_yaml(data: Any) -> str:
    """``data`` as YAML for people: keys in their order, 100 columns, no anchors."""
    return yaml.dump(data, Dumper=_PlainDumper, sort_keys=False, width=100)


class PlantParametersError(ScenarioError):
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
    intervals : dict
        Per parameter name, the range (low, high) its value may take as far as what made the
        file can tell (units of ``parameters``); robust tuning samples within them.
    """

    model: str
    parameters: dict[str, float]
    provenance: dict[str, dict[str, Any]] = field(default_factory=dict)
    created_by: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """The file's content (YAML-ready)."""
        content: dict[str, Any] = {
            "model": self.model,
            "parameters": dict(self.parameters),
            "provenance": self.provenance,
        }
        if self.intervals:
            content["intervals"] = {k: [low, high] for k, (low, high) in self.intervals.items()}
        return {**content, "created_by": self.created_by}


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

    Raises
    ------
    PlantParametersError
        Naming the file, the key and the expected unit and range.
    """
    try:
        known = plant_model(model).parameters
    except PlantModelError as exc:
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
        problem = range_problem(variable, value)
        if problem:
            raise PlantParametersError(f"{at}: {problem}")
        checked[str(name)] = value
    return checked


def range_problem(variable: Variable, value: float) -> str:
    """Why the FMU would refuse ``value`` for a parameter (its range in the variable table),
    '' when it would not."""
    low = variable.min if variable.min is not None else -math.inf
    high = variable.max if variable.max is not None else math.inf
    if low <= value <= high and not (variable.positive and value <= 0):
        return ""
    limits = f"(0, {high:g}]" if variable.positive and low <= 0 else f"[{low:g}, {high:g}]"
    return f"{value:.6g} {variable.unit} outside the model's range {limits}"


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
    check = Checker(path, PlantParametersError)
    data = load_yaml(path, PlantParametersError)
    if not isinstance(data, dict):
        raise PlantParametersError(f"{path}: expected a mapping with keys {sorted(TOP_KEYS)}")
    check.mapping(data, "(top level)", TOP_KEYS)
    found = data.get("model")
    if not isinstance(found, str):
        raise check.fail("model", "a plant model name", found)
    try:
        plant_model(found)
    except PlantModelError as exc:
        raise PlantParametersError(f"{path}: model: {exc}") from exc
    if model is not None and found != model:
        raise PlantParametersError(
            f"{path}: model: the file is for plant model {found!r}, the scenario's plant is "
            f"{model!r}"
        )
    values = data.get("parameters")
    if not isinstance(values, dict):
        raise check.fail("parameters", "a mapping name -> value")
    provenance = data.get("provenance") or {}
    if not isinstance(provenance, dict) or not all(
        isinstance(v, dict) and "source" in v for v in provenance.values()
    ):
        raise check.fail("provenance", "a mapping name -> {source: text, ...}")
    stray = sorted(set(provenance) - set(values))
    if stray:
        raise PlantParametersError(f"{path}: provenance: names without a parameter value {stray}")
    created_by = check.mapping(data.get("created_by"), "created_by")
    checked = check_values(values, found, str(path))
    intervals = check_intervals(data.get("intervals") or {}, checked, found, str(path))
    return PlantParameters(found, checked, provenance, created_by, path, intervals)


def check_intervals(
    intervals: Any, values: Mapping[str, float], model: str, where: str
) -> dict[str, tuple[float, float]]:
    """Check the ``intervals`` of a plant file: per parameter of the model a pair [low, high],
    low <= high, both inside the variable table's range, holding the parameter's value when
    the file gives one.

    Raises
    ------
    PlantParametersError
        Naming the file, the key and what was expected.
    """
    if not isinstance(intervals, dict):
        raise PlantParametersError(f"{where}: intervals: expected a mapping name -> [low, high]")
    checked = {}
    for name, pair in intervals.items():
        at = f"intervals.{name}"
        if not (isinstance(pair, list) and len(pair) == 2):
            raise PlantParametersError(f"{where}: {at}: expected a pair [low, high], got {pair!r}")
        low, high = (check_values({name: end}, model, where, "intervals")[name] for end in pair)
        if low > high:
            raise PlantParametersError(f"{where}: {at}: low {low!r} above high {high!r}")
        value = values.get(name)
        if value is not None and not low <= value <= high:
            raise PlantParametersError(
                f"{where}: {at}: [{low!r}, {high!r}] does not hold the parameter's value {value!r}"
            )
        checked[str(name)] = (low, high)
    return checked


def fitted_plant(
    model: str, parameters: Mapping[str, float], source: str, command: str, **details: Any
) -> PlantParameters:
    """A plant parameter file of values a command fitted: each value's provenance ``source``
    (text), ``created_by`` the command line, the version and ``details``."""
    from twin_cosim.versions import versions

    return PlantParameters(
        model=model,
        parameters=dict(parameters),
        provenance={name: {"source": source} for name in parameters},
        created_by={"command": command, "version": versions()["twin-cosim"], **details},
    )


def write_plant_parameters(path: Path | str, plant: PlantParameters) -> Path:
    """Write a plant parameter file (values and intervals are checked first; floats
    round-trip exactly)."""
    check_values(plant.parameters, plant.model, str(path))
    check_intervals(
        {k: list(v) for k, v in plant.intervals.items()}, plant.parameters, plant.model, str(path)
    )
    path = Path(path)
    path.write_text(dump_yaml(plant.as_dict()))
    return path


SCENARIO_PATHS = (
    ("plant", "fmu"),
    ("plant", "parameters_file"),
    ("reference", "csv"),
    ("reference", "measured"),
)


def relocate_paths(data: dict[str, Any], source_dir: Path, target_dir: Path) -> None:
    """Rewrite in place the relative paths a scenario file's ``data`` names
    (:data:`SCENARIO_PATHS`), written for ``source_dir``, relative to ``target_dir``: a copy of
    the scenario written elsewhere names the same files."""
    for section, key in SCENARIO_PATHS:
        body = data.get(section)
        if isinstance(body, dict) and key in body:
            path = Path(str(body[key]))
            if not path.is_absolute():
                body[key] = os.path.relpath((source_dir / path).resolve(), target_dir.resolve())


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
    data["plant"] = plant_section
    relocate_paths(data, scenario_file.parent, out.parent)
    data["description"] = (
        f"{data.get('description', '')} Calibrated: the plant parameters of the plant.yaml "
        "beside this file folded in."
    ).strip()
    out.write_text(dump_yaml(data))
    return out
