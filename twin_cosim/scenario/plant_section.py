"""The ``plant`` section of a scenario and the one precedence rule of plant parameters.

Layout::

    plant:
      model: drive2mass         # a folder of models/ (the default), built when first run; or
      fmu: other.fmu            # an FMU file, relative to the scenario file
      parameters: {backlash: 12.2e-6}        # FMU parameters by name
      parameters_file: plant.yaml            # a calibrated plant (twin_cosim.scenario.plant_file),
                                             # relative to the scenario file; its names must not
                                             # be repeated in parameters

Plant parameter values, lowest precedence first: the model's start values (its variable table),
the scenario's ``plant.parameters``, the scenario's ``plant.parameters_file``, then a
command-line ``--plant-parameters`` file (:func:`with_plant_parameters`). The drive's plant facts
(travel per radian, inertia, torque constant, friction, speed-loop period) follow from the
result through the model's card (:mod:`twin_cosim.plant_model`); ``controller.settings`` may
still set any of them (a drive commissioned with other values than the plant's).

Reading a plant section never compiles C: a ``model`` is built when a run first needs its FMU.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fmu_build.build import DEFAULT_MODEL
from twin_cosim.plant_model import fmu_identity, model_names, model_of, plant_model
from twin_cosim.scenario.plant_file import (
    PlantParametersError,
    check_values,
    read_plant_parameters,
)
from twin_cosim.scenario.resolved import Scenario
from twin_cosim.schema import Checker, ScenarioError

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
