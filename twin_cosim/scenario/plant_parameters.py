"""The plant of a scenario and its parameters: the ``plant`` section, the one precedence rule of
plant parameters, and plant parameter files (``plant.yaml``).

**The plant section.** Layout::

    plant:
      model: drive2mass         # a folder of models/ (the default), built when first run; or
      fmu: other.fmu            # an FMU file, relative to the scenario file
      parameters: {backlash: 12.2e-6}        # FMU parameters by name
      parameters_file: plant.yaml            # a calibrated plant (a plant.yaml file, below),
                                             # relative to the scenario file; its names must not
                                             # be repeated in parameters

Plant parameter values, lowest precedence first: the model's start values (its variable table),
the scenario's ``plant.parameters``, the scenario's ``plant.parameters_file``, then a
command-line ``--plant-parameters`` file (:func:`with_plant_parameters`). The drive's plant facts
(travel per radian, inertia, torque constant, friction, speed-loop period) follow from the
result through the model's card (:mod:`twin_cosim.plant_model`); ``controller.settings`` may
still set any of them (a drive commissioned with other values than the plant's).

Reading a plant section never compiles C: a ``model`` is built when a run first needs its FMU.

**Plant parameter files** (``plant.yaml``): a calibrated plant that any scenario can take.

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
    model_error:                          # what the twin still misses on its held-out runs
      position_peak_m: 9.2e-08            # (twin_cosim.model_error): largest and RMS scale
      position_rms_m: 2.0e-08             # discrepancy, m, and RMS current discrepancy, A;
      current_rms_A: 0.005                # a prediction's interval is widened by them
    created_by: {command: "twin diagnose ...", version: 0.1.0, measured: [...], holdout: ...}

It is read with the scenarios' YAML loader and checker (:mod:`twin_cosim.schema`), so a value
reads the same in both (``2e-5`` is a number). Reading checks the model, that every name is a
parameter of the model's variable table, and that every value is finite and inside the table's
range, that each interval is a pair [low, high] inside that range holding the parameter's
value, and that ``model_error`` holds its three figures, each finite and >= 0 (the largest
position discrepancy at least its RMS); errors name the file and the key. Writing spells every
value out where it stands (no YAML anchors and aliases for a person editing the file to
decode).

:func:`calibrated_scenario` folds such a file into a copy of a scenario file
(``calibrated.yaml`` beside a diagnosis' ``plant.yaml``).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fmu_build.build import DEFAULT_MODEL
from fmu_build.variable_table import Variable
from twin_cosim.model_error import FIELDS as MODEL_ERROR_FIELDS
from twin_cosim.model_error import ModelError
from twin_cosim.plant_model import PlantModelError, fmu_identity, model_names, model_of, plant_model
from twin_cosim.scenario.resolved import Scenario
from twin_cosim.schema import Checker, ScenarioError, load_yaml

TOP_KEYS = {"model", "parameters", "provenance", "intervals", "model_error", "created_by"}


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
    model_error : ModelError or None
        What the twin with these values still misses on the runs held out from what made the
        file (a diagnosis); a prediction's interval is widened by it.
    """

    model: str
    parameters: dict[str, float]
    provenance: dict[str, dict[str, Any]] = field(default_factory=dict)
    created_by: dict[str, Any] = field(default_factory=dict)
    source: Path | None = None
    intervals: dict[str, tuple[float, float]] = field(default_factory=dict)
    model_error: ModelError | None = None

    def as_dict(self) -> dict[str, Any]:
        """The file's content (YAML-ready)."""
        content: dict[str, Any] = {
            "model": self.model,
            "parameters": dict(self.parameters),
            "provenance": self.provenance,
        }
        if self.intervals:
            content["intervals"] = {k: [low, high] for k, (low, high) in self.intervals.items()}
        if self.model_error is not None:
            content["model_error"] = self.model_error.as_dict()
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
    model_error = _model_error(check, data.get("model_error"))
    return PlantParameters(found, checked, provenance, created_by, path, intervals, model_error)


def _model_error(check: Checker, raw: Any) -> ModelError | None:
    """The ``model_error`` section: all of its figures, each finite and >= 0, the largest
    position discrepancy at least its RMS; None without it."""
    if raw is None:
        return None
    section = check.mapping(raw, "model_error", set(MODEL_ERROR_FIELDS))
    missing = [name for name in MODEL_ERROR_FIELDS if name not in section]
    if missing:
        raise check.fail("model_error", f"all of {list(MODEL_ERROR_FIELDS)}; missing {missing}")
    figures = [
        check.number(section[name], f"model_error.{name}", minimum=0.0)
        for name in MODEL_ERROR_FIELDS
    ]
    error = ModelError(*figures)
    if error.position_peak_m < error.position_rms_m:
        raise check.fail(
            "model_error.position_peak_m", "at least position_rms_m", error.position_peak_m
        )
    return error


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


def calibrated_scenario(
    scenario_file: Path | str,
    plant: PlantParameters,
    out: Path | str,
    drive: Mapping[str, float] | None = None,
) -> Path:
    """Write ``out``: the scenario file with the calibrated values folded into plant.parameters.

    Values of a ``plant.parameters_file`` are folded in too (the file key is dropped); the
    calibrated values win. Paths the scenario names (``plant.fmu``, ``reference.csv``,
    ``reference.measured``) are rewritten relative to the new file's folder.

    ``drive``: the drive's plant facts as the scenario's controller had them (its loaded
    settings, :data:`~twin_cosim.plant_model.DRIVE_FACTS`), written into
    ``controller.settings`` where the file does not set them: the drive was commissioned with
    those values, and a calibrated plant does not change them (without this, the facts would
    follow the calibrated plant, the controller's friction and inertia terms with them, and
    the file would replay another twin than ``--plant-parameters`` applies).
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
    if drive:
        controller = dict(data.get("controller") or {})
        settings = dict(controller.get("settings") or {})
        controller["settings"] = {**{k: float(v) for k, v in drive.items()}, **settings}
        data["controller"] = controller
    relocate_paths(data, scenario_file.parent, out.parent)
    data["description"] = (
        f"{data.get('description', '')} Calibrated: the plant parameters of the plant.yaml "
        "beside this file folded in, the drive's settings as they were."
    ).strip()
    out.write_text(dump_yaml(data))
    return out


PLANT_KEYS = {"fmu", "model", "parameters", "parameters_file"}


@dataclass(frozen=True)
class PlantSection:
    """A checked ``plant`` section.

    Attributes
    ----------
    model : str or None
        The plant model (folder of models/); None for an FMU file.
    fmu : Path or None
        The FMU file the scenario names; None for a model.
    parameters : dict
        FMU parameter values by name (SI units): ``plant.parameters`` with the values of
        ``plant.parameters_file`` underneath.
    parameters_file : Path or None
        The ``plant.parameters_file`` given.
    """

    model: str | None
    fmu: Path | None
    parameters: dict[str, float]
    parameters_file: Path | None


def plant_section(check: Checker, data: Any) -> PlantSection:
    """Read and check the ``plant`` section of the scenario file ``check.source``."""
    source = Path(check.source)
    plant = check.mapping(data, "plant", PLANT_KEYS)
    parameters = {
        str(k): check.number(v, f"plant.parameters.{k}")
        for k, v in check.mapping(plant.get("parameters"), "plant.parameters").items()
    }
    if "fmu" in plant and "model" in plant:
        raise check.fail(
            "plant", "either 'fmu' (a file) or 'model' (a folder of models/), not both"
        )
    fmu = None if plant.get("fmu") is None else source.parent / str(plant["fmu"])
    model = None if fmu is not None else str(plant.get("model", DEFAULT_MODEL))
    if model is not None and model not in model_names():
        raise check.fail("plant.model", f"one of the project's models {model_names()}", model)
    if model is not None:
        try:  # each value in the model's range and unit, named by its key
            check_values(parameters, model, str(source), f"{check.prefix}plant.parameters")
        except PlantParametersError as exc:
            raise ScenarioError(str(exc)) from exc
    parameters_file = None
    if "parameters_file" in plant:
        parameters_file = source.parent / str(plant["parameters_file"])
        parameters = _with_parameters_file(check, parameters, parameters_file, model, fmu)
    if model is not None:
        where = {n: f"{check.prefix}plant.parameters.{n}" for n in plant.get("parameters") or {}}
        file_keys = set(parameters) - set(where)
        where |= dict.fromkeys(file_keys, f"{check.prefix}plant.parameters_file {parameters_file}")
        check_constraints(model, parameters, where, str(source))
    return PlantSection(model, fmu, parameters, parameters_file)


def check_constraints(
    model: str, parameters: dict[str, float], where: dict[str, str], source: str
) -> None:
    """Refuse plant parameters that break a constraint of the model's card (what its FMU
    refuses at initialisation), naming the keys (``where``: parameter -> key) that set them.

    Raises
    ------
    ScenarioError
        Naming the file, the keys, the values and the constraint.
    """
    broken = plant_model(model).broken_constraints(parameters)
    if not broken:
        return
    text, names = broken[0]
    keys = sorted({where[n] for n in names if n in where})
    raise ScenarioError(
        f"{source}: {', '.join(keys) or 'plant.parameters'}: the plant would break {text}; the "
        f"FMU of {model} refuses it (models/{model}/card.yaml, constraints)"
    )


def _with_parameters_file(
    check: Checker, parameters: dict[str, float], path: Path, model: str | None, fmu: Path | None
) -> dict[str, float]:
    """The scenario's plant parameters plus those of ``plant.parameters_file`` (no name twice)."""
    try:
        calibrated = read_plant_parameters(path, model or model_of(fmu)).parameters
    except (PlantParametersError, ValueError) as exc:
        raise ScenarioError(f"{check.where('plant.parameters_file')}: {exc}") from exc
    twice = sorted(set(parameters) & set(calibrated))
    if twice:
        raise check.fail(
            "plant.parameters", f"no name also set by plant.parameters_file {path}", twice
        )
    return {**calibrated, **parameters}


def check_friction_below_peak_torque(
    check: Checker, section: PlantSection, current_limit: float
) -> None:
    """The plant's friction torque must stay below the drive's peak torque (the current limit
    times the torque constant): an axis that can never move is a parameter in the wrong unit
    (``coulomb_friction: 625`` for 0.625 N.m), named by its key.

    Raises
    ------
    ScenarioError
        Naming each ``plant.parameters`` key that lifts the friction to the peak torque.
    """
    if section.model is None:
        return
    card = plant_model(section.model)
    facts = card.drive_facts(section.parameters)
    peak = current_limit * facts["torque_constant"]
    if facts["friction_torque"] < peak:
        return
    starts = card.start_values()
    culprits = [
        name
        for name in section.parameters
        if name in starts
        and card.drive_facts({**section.parameters, name: starts[name]})["friction_torque"] < peak
    ]
    keys = ", ".join(
        f"{check.prefix}plant.parameters.{n} = {section.parameters[n]:g}" for n in culprits
    )
    raise ScenarioError(
        f"{check.source}: {keys or check.prefix + 'plant.parameters'}: the friction torque "
        f"{facts['friction_torque']:.4g} N.m reaches the drive's peak torque {peak:.4g} N.m "
        f"(current limit {current_limit:g} A x torque constant {facts['torque_constant']:.4g} "
        f"N.m/A): the axis could never move; is a value in another unit? (units: "
        f"models/{section.model}/variables.yaml)"
    )


def drive_facts(check: Checker, section: PlantSection) -> dict[str, float]:
    """The drive's plant facts from the model's card at the section's parameter values.

    An FMU file of one of the project's models (by its model identifier) takes that model's
    card over its own start values; an FMU of another model has no card, and the controller
    settings keep their defaults unless the scenario sets them.
    """
    if section.model is not None:
        return plant_model(section.model).drive_facts(section.parameters)
    if section.fmu is None or not section.fmu.is_file():
        return {}
    try:
        identifier, _, starts = fmu_identity(section.fmu)
    except Exception as exc:  # noqa: BLE001 - a broken FMU is reported when it is loaded to run
        raise ScenarioError(f"{check.where('plant')}: cannot read its parameters: {exc}") from exc
    if identifier not in model_names():
        return {}
    return plant_model(identifier).drive_facts({**starts, **section.parameters})


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
    model = scenario.model_name(fmu)
    plant = read_plant_parameters(path, model)
    check_constraints(
        model,
        {**scenario.plant_parameters, **plant.parameters},
        {name: f"parameters.{name}" for name in plant.parameters},
        str(path),
    )
    return dataclasses.replace(
        scenario,
        plant_parameters={**scenario.plant_parameters, **plant.parameters},
        plant_parameters_file=Path(path),
    )


def plant_mismatch(scenario: Scenario, fmu: Path | str) -> str | None:
    """A warning when ``fmu`` is not the plant model the scenario was made for, else None.

    The scenario names its model (``plant.model``, drive2mass by default) or its FMU
    (``plant.fmu``); another model identifier or another set of variables in ``fmu`` is a
    mismatch: the scenario's controller settings and plant parameters were chosen for another
    plant.
    """
    if scenario.model is not None:
        expected, expected_names = scenario.model, plant_model(scenario.model).variable_names
    elif scenario.fmu is not None and scenario.fmu.is_file():
        expected, expected_names, _ = fmu_identity(scenario.fmu)
    else:
        return None
    try:
        identifier, names, _ = fmu_identity(Path(fmu))
    except Exception:  # noqa: BLE001 - not readable: Plant reports it when the FMU is loaded
        return None
    if identifier == expected and names == expected_names:
        return None
    differences = []
    if names != expected_names:
        missing, extra = sorted(expected_names - names), sorted(names - expected_names)
        differences.append(
            f"variables missing: {missing[:5]}{' ...' if len(missing) > 5 else ''}, "
            f"variables added: {extra[:5]}{' ...' if len(extra) > 5 else ''}"
        )
    return (
        f"{scenario.source} was made for the plant model {expected!r}, but {fmu} is model "
        f"{identifier!r}" + (f" ({differences[0]})" if differences else "") + ": its controller "
        "settings and plant parameters were chosen for another plant"
    )
