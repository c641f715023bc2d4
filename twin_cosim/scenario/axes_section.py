"""The ``axes`` section of a machine scenario: one plant, controller and limits per axis.

Layout::

    axes:
      X:
        plant: {model: drive2mass, parameters: {}, parameters_file: x_plant.yaml}
        controller: {parameters: ft, settings: {}}
        limits: {velocity: 0.25, acceleration: 2.0, jerk: 40.0}    # m/s, m/s^2, m/s^3
      Y: {...}
      Z: {...}                                  # optional

``X`` and ``Y`` are required, ``Z`` optional. Each axis' ``plant`` and ``controller`` read as the
sections of a single-axis scenario (:mod:`~twin_cosim.scenario.plant_section`,
:mod:`~twin_cosim.scenario.controller_section`); every error names the file and the full key
path (``axes.Y.plant.parameters.backlash``). All axes must share the CNC's rates (position- and
speed-loop periods): the master steps them in lockstep.
"""

from __future__ import annotations

from typing import Any

from twin_cosim.scenario.controller_section import controller_section
from twin_cosim.scenario.machine import AXIS_NAMES, AxisLimits, AxisSetup
from twin_cosim.scenario.plant_section import plant_section
from twin_cosim.schema import Checker

AXIS_KEYS = {"plant", "controller", "limits"}
DEFAULT_LIMITS = AxisLimits(velocity=0.25, acceleration=2.0, jerk=40.0)


def axes_section(check: Checker, data: Any) -> tuple[AxisSetup, ...]:
    """The checked axes of ``axes:``, in the order X, Y, Z."""
    axes = check.mapping(data, "axes", set(AXIS_NAMES))
    for required in ("X", "Y"):
        if required not in axes:
            raise check.fail(f"axes.{required}", "a section for this axis (X and Y are required)")
    found = tuple(
        _axis(
            check.within(f"axes.{name}"),
            name,
            check.mapping(axes[name], f"axes.{name}", AXIS_KEYS),
        )
        for name in AXIS_NAMES
        if name in axes
    )
    first = found[0].settings
    for axis in found[1:]:
        for rate in ("position_period", "speed_period"):
            if getattr(axis.settings, rate) != getattr(first, rate):
                raise check.fail(
                    f"axes.{axis.name}.controller.settings.{rate}",
                    f"the {rate} of axis {found[0].name} ({getattr(first, rate):g} s): the "
                    "master steps all axes in lockstep",
                    getattr(axis.settings, rate),
                )
    return found


def _axis(check: Checker, name: str, body: dict[str, Any]) -> AxisSetup:
    plant = plant_section(check, body.get("plant"))
    tuned, settings = controller_section(check, plant, body.get("controller"))
    return AxisSetup(
        name=name,
        model=plant.model,
        fmu=plant.fmu,
        plant_parameters=dict(plant.parameters),
        plant_parameters_file=plant.parameters_file,
        tuned=tuned,
        settings=settings,
        limits=_limits(check, body.get("limits")),
    )


def _limits(check: Checker, data: Any) -> AxisLimits:
    given = check.mapping(data, "limits", {"velocity", "acceleration", "jerk"})
    values = {
        key: check.number(
            given.get(key, getattr(DEFAULT_LIMITS, key)), f"limits.{key}", positive=True
        )
        for key in ("velocity", "acceleration", "jerk")
    }
    return AxisLimits(**values)
