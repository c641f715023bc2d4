"""The ``controller.settings`` of a scenario (or of one axis): fixed settings, plant facts and
current filters.

Layout::

    controller:
      settings:
        current_limit: 20.0                # any field of twin_cosim.controller.ControllerSettings
        ff_acceleration: 1.0
        filters:                           # current-setpoint filter chain, in this order
          - {type: notch, frequency_hz: 109.5, bandwidth_hz: 60.0, depth_db: -20.0}
          - {type: lowpass, frequency_hz: 1500.0, damping: 0.7071}

The plant facts (travel per radian, inertia, torque constant, friction, speed-loop period) come
from the plant model's card at the scenario's plant parameters; ``controller.settings`` may set
any of them on top. Filter forms: :mod:`twin_cosim.current_filters`.
"""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings
from twin_cosim.current_filters import CurrentFilter
from twin_cosim.plant_model import DRIVE_FACTS
from twin_cosim.schema import Checker, ScenarioError

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
