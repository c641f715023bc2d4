"""The ``controller`` section of a scenario (or of one axis): the six tuned parameters, the
fixed settings with the plant facts and the current filters; and controller sets (``--params``,
``--start``): the six and the fixed settings a tuner changed.

Layout::

    controller:
      parameters: {Kp_pos: 66.667, ...}    # the six tuned parameters, or the name of a set of
                                           # the paper's Table 3 (ft, ga, ce, sa); default: ft
      settings:
        current_limit: 20.0                # any field of twin_cosim.controller.ControllerSettings
        ff_acceleration: 1.0
        filters:                           # current-setpoint filter chain, in this order
          - {type: notch, frequency_hz: 109.5, bandwidth_hz: 60.0, depth_db: -20.0}
          - {type: lowpass, frequency_hz: 1500.0, damping: 0.7071}

The settings start from the plant's drive facts (travel per radian, inertia, torque constant,
friction, speed-loop period: the plant model's card at the scenario's plant parameters); the
``settings`` given win over them. Filter forms: :mod:`twin_cosim.current_filters`.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

from twin_cosim import current_filters
from twin_cosim.controller import TUNED_NAMES, ControllerSettings, TunedParameters
from twin_cosim.controller_set import TABLE3, ControllerSet
from twin_cosim.current_filters import CurrentFilter
from twin_cosim.plant_model import DRIVE_FACTS
from twin_cosim.scenario.plant_parameters import PlantSection, drive_facts
from twin_cosim.schema import Checker, ScenarioError, load_yaml

SETTING_NAMES = {f.name for f in fields(ControllerSettings)}


def controller_settings(check: Checker, facts: dict[str, float], raw: Any) -> ControllerSettings:
    """Controller settings: the plant's drive ``facts``, then ``controller.settings`` on top."""
    given = check.mapping(raw, "controller.settings", SETTING_NAMES)
    numbers = {
        k: check.number(v, f"controller.settings.{k}") for k, v in given.items() if k != "filters"
    }
    filters = filters_section(check, given.get("filters"), "controller.settings.filters")
    try:
        return ControllerSettings(
            **{name: facts[name] for name in DRIVE_FACTS if name in facts} | numbers,
            filters=filters,
        )
    except ValueError as exc:
        raise ScenarioError(f"{check.where('controller.settings')}: {exc}") from exc


def filters_section(check: Checker, data: Any, key: str) -> tuple[CurrentFilter, ...]:
    """A list of filter sections (none when ``data`` is None); errors name the entry."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise check.fail(key, "a list of filter sections ({type: notch|lowpass, ...})", data)
    sections = []
    for index, entry in enumerate(data):
        if not isinstance(entry, dict):
            raise check.fail(f"{key}[{index}]", "a mapping {type: notch|lowpass, ...}", entry)
        try:
            sections.append(current_filters.from_dict(entry))
        except ValueError as exc:
            raise check.error(f"{check.where(f'{key}[{index}]')}: {exc}") from None
    return tuple(sections)


def tuned_section(data: Any, where: str) -> TunedParameters:
    """Tuned parameters from a mapping, or the name of a set of the paper's Table 3."""
    if isinstance(data, str):
        if data.lower() not in TABLE3:
            raise ScenarioError(
                f"{where}: expected the six parameters or a set of Table 3 {sorted(TABLE3)}"
                f", got {data!r}"
            )
        return TABLE3[data.lower()]
    return tuned_from_mapping(data, where)


def tuned_from_mapping(data: Any, where: str) -> TunedParameters:
    """The six tuned parameters from a mapping that must hold exactly those names.

    Raises
    ------
    ScenarioError
        Naming ``where`` (file and key) on a missing, unknown or invalid value.
    """
    if not isinstance(data, dict):
        raise ScenarioError(f"{where}: expected a mapping of {list(TUNED_NAMES)}")
    missing = [n for n in TUNED_NAMES if n not in data]
    unknown = sorted(set(data) - set(TUNED_NAMES))
    if missing or unknown:
        raise ScenarioError(
            f"{where}: missing {missing}, unknown {unknown}; expected exactly {list(TUNED_NAMES)}"
        )
    values = {}
    for name in TUNED_NAMES:
        value = data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f"{where}.{name}: expected a number, got {value!r}")
        values[name] = float(value)
    try:
        return TunedParameters(**values)
    except ValueError as exc:
        raise ScenarioError(f"{where}: {exc}") from exc


def load_controller_set(spec: str) -> ControllerSet:
    """A controller set for ``--params``: a Table 3 set name (ft, ga, ce, sa) or a file.

    The YAML/JSON file holds the six names at the top level, or under ``params`` (what
    ``twin autotune`` prints) or ``best_params`` (what ``twin optimize`` writes), with the fixed
    settings it changes under ``settings`` (:mod:`twin_cosim.controller_set`).
    """
    if spec.lower() in TABLE3:
        return ControllerSet(TABLE3[spec.lower()])
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(
            f"--params {spec}: neither a set of Table 3 {sorted(TABLE3)} nor a file"
        )
    data = load_yaml(path)
    for key in ("params", "best_params"):
        if isinstance(data, dict) and key in data:
            block = data[key]  # filter dimensions of a campaign (filter1.frequency_hz) aside
            if isinstance(block, dict):
                block = {k: v for k, v in block.items() if "." not in str(k)}
            tuned = tuned_from_mapping(block, f"{path}: {key}")
            return ControllerSet(tuned, settings_overrides(path, data.get("settings")))
    return ControllerSet(tuned_from_mapping(data, str(path)))


def settings_overrides(path: Path, data: Any) -> dict[str, Any]:
    """The ``settings`` of a controller-set file: fields of ControllerSettings, filters as
    sections; errors name the file and the key."""
    check = Checker(path)
    given = check.mapping(data, "settings", SETTING_NAMES)
    overrides: dict[str, Any] = {
        k: check.number(v, f"settings.{k}") for k, v in given.items() if k != "filters"
    }
    if "filters" in given:
        overrides["filters"] = filters_section(check, given["filters"], "settings.filters")
    return overrides


def load_axes_parameters(spec: str, axes: tuple[str, ...]) -> dict[str, TunedParameters]:
    """Parameters of each axis of a machine for ``--params``.

    A Table 3 set name, or a file of one set, gives every axis that set; a file with ``axes:``
    (``{X: {Kp_pos: ...}, Y: {...}}``, at the top level or under ``best_params``: what a contour
    campaign writes) gives each axis its own, the axes it does not name keep theirs.
    """
    if spec.lower() in TABLE3:
        return dict.fromkeys(axes, TABLE3[spec.lower()])
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(
            f"--params {spec}: neither a set of Table 3 {sorted(TABLE3)} nor a file"
        )
    data = load_yaml(path)
    where = str(path)
    if isinstance(data, dict) and "best_params" in data:
        data, where = data["best_params"], f"{path}: best_params"
    if not (isinstance(data, dict) and "axes" in data):
        return dict.fromkeys(axes, tuned_from_mapping(data, where))
    given = data["axes"]
    if not isinstance(given, dict) or not set(given) <= set(axes):
        raise ScenarioError(f"{where}: axes: expected a mapping of the machine's axes {list(axes)}")
    return {name: tuned_from_mapping(given[name], f"{where}: axes.{name}") for name in given}


def controller_section(
    check: Checker, plant: PlantSection, data: Any
) -> tuple[TunedParameters, ControllerSettings]:
    """The tuned parameters and the settings of a ``controller`` section for ``plant``."""
    control = check.mapping(data, "controller", {"parameters", "settings"})
    tuned = tuned_section(control.get("parameters", "ft"), check.where("controller.parameters"))
    settings = controller_settings(check, drive_facts(check, plant), control.get("settings"))
    return tuned, settings
