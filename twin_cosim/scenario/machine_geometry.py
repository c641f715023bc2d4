"""The geometric errors of a machine: where the tool point is, given the axes' positions.

Each axis' position is what its scale reads (the position the loop closes on). The tool point
that a ballbar or a part sees differs from it by the machine's geometry, the ``geometry:``
section of a machine scenario (every value optional, 0 by default)::

    geometry:
      squareness: 20.0                  # um/m: + when the angle between +X and +Y exceeds 90 deg
      scale: {X: 15.0, Y: -10.0}        # um/m: each axis' scale error (+: the tool goes further)
      straightness: {X: 4.0, Y: 0.0}    # um: each axis' bow over its travel (limits.travel),
                                        # + toward + of the other axis (X's toward +Y)
      cyclic: {X: {amplitude_um: 1.5, period_mm: 10.0}}   # each axis' cyclic (pitch) error

With the axes' positions x, y (m) and the errors in SI (scale s, squareness alpha in rad, bow
b over a travel of centre c and half-length h, cyclic amplitude A and period P)::

    x_s = x (1 + s_X) + A_X sin(2 pi x / P_X)       y_s = y (1 + s_Y) + A_Y sin(2 pi y / P_Y)
    x_t = x_s - alpha y_s + b_Y (1 - ((y - c_Y) / h_Y)^2)
    y_t = y_s + b_X (1 - ((x - c_X) / h_X)^2)

(first order in the errors: the +Y axis runs along (-alpha, 1), so that the angle between +X and
+Y is 90 deg + alpha; a straightness bow is 0 at both ends of the travel and b in its middle).
A Z axis has no geometric errors here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin_cosim.schema import Checker

UM = 1e-6  # m per um
MM = 1e-3  # m per mm
PLANE = ("X", "Y")
GEOMETRY_KEYS = {"squareness", "scale", "straightness", "cyclic"}


@dataclass(frozen=True)
class CyclicError:
    """A cyclic error along one axis: the tool is off by ``amplitude sin(2 pi x / period)``.

    Attributes
    ----------
    amplitude : float
        Amplitude, m.
    period : float
        Period along the axis, m (a screw's lead, a scale's grating period).
    """

    amplitude: float
    period: float


@dataclass(frozen=True)
class MachineGeometry:
    """The geometric errors between the axes' positions and the tool point (module docstring).

    Attributes
    ----------
    squareness : float
        Squareness of Y to X, rad: + when the angle between +X and +Y exceeds 90 deg.
    scale : dict
        Axis name -> scale error, 1 (m/m).
    straightness : dict
        Axis name -> bow over its travel, m (+ toward + of the other axis).
    travel : dict
        Axis name -> (low, high) travel, m: where the bow of an axis with straightness is 0.
    cyclic : dict
        Axis name -> its :class:`CyclicError`.
    """

    squareness: float = 0.0
    scale: dict[str, float] = field(default_factory=dict)
    straightness: dict[str, float] = field(default_factory=dict)
    travel: dict[str, tuple[float, float]] = field(default_factory=dict)
    cyclic: dict[str, CyclicError] = field(default_factory=dict)

    @property
    def is_ideal(self) -> bool:
        """Whether the tool point is the axes' positions (no error at all)."""
        return (
            self.squareness == 0.0
            and not any(self.scale.values())
            and not any(self.straightness.values())
            and not any(c.amplitude for c in self.cyclic.values())
        )

    def _bow(self, axis: str, position: np.ndarray) -> np.ndarray:
        """The bow of ``axis`` at its positions (m): 0 at both ends of the travel."""
        bow = self.straightness.get(axis, 0.0)
        if bow == 0.0:
            return np.zeros_like(position)
        low, high = self.travel[axis]
        centre, half = (low + high) / 2, (high - low) / 2
        return bow * (1.0 - ((position - centre) / half) ** 2)

    def _along(self, axis: str, position: np.ndarray) -> np.ndarray:
        """The axis' own direction: its scale and cyclic errors applied (m)."""
        moved = position * (1.0 + self.scale.get(axis, 0.0))
        cyclic = self.cyclic.get(axis)
        if cyclic is not None and cyclic.amplitude:
            moved = moved + cyclic.amplitude * np.sin(2 * math.pi * position / cyclic.period)
        return moved

    def tool_point(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tool point (m) where the X and Y axes read ``x`` and ``y`` (m)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if self.is_ideal:
            return x, y
        x_s, y_s = self._along("X", x), self._along("Y", y)
        return x_s - self.squareness * y_s + self._bow("Y", y), y_s + self._bow("X", x)

    def as_dict(self) -> dict[str, Any]:
        """The section as written (um/m, um, mm), for JSON files."""
        return {
            "squareness": self.squareness / UM,
            "scale": {axis: value / UM for axis, value in self.scale.items()},
            "straightness": {axis: value / UM for axis, value in self.straightness.items()},
            "cyclic": {
                axis: {"amplitude_um": c.amplitude / UM, "period_mm": c.period / MM}
                for axis, c in self.cyclic.items()
            },
        }


def geometry_section(
    check: Checker, data: Any, travel: dict[str, tuple[float, float] | None]
) -> MachineGeometry:
    """The checked ``geometry:`` section; ``travel`` (m) is each axis' ``limits.travel``, which
    a straightness bow needs.

    Raises
    ------
    ScenarioError
        Naming the file and the key, e.g. ``geometry.scale.X: expected a number``.
    """
    given = check.mapping(data, "geometry", GEOMETRY_KEYS)
    scale = _per_axis(check, given.get("scale"), "geometry.scale")
    bows = _per_axis(check, given.get("straightness"), "geometry.straightness")
    for axis, bow in bows.items():
        if bow and travel.get(axis) is None:
            raise check.fail(
                f"axes.{axis}.limits.travel",
                f"a travel [low, high] in m: geometry.straightness.{axis} is a bow over it",
            )
    cyclic = {}
    for axis, value in check.mapping(given.get("cyclic"), "geometry.cyclic", set(PLANE)).items():
        key = f"geometry.cyclic.{axis}"
        entry = check.mapping(value, key, {"amplitude_um", "period_mm"})
        for name in ("amplitude_um", "period_mm"):
            if name not in entry:
                raise check.fail(f"{key}.{name}", "a number (amplitude um, period mm)")
        cyclic[axis] = CyclicError(
            amplitude=check.number(entry["amplitude_um"], f"{key}.amplitude_um", minimum=0.0) * UM,
            period=check.number(entry["period_mm"], f"{key}.period_mm", positive=True) * MM,
        )
    return MachineGeometry(
        squareness=check.number(given.get("squareness", 0.0), "geometry.squareness") * UM,
        scale={axis: value * UM for axis, value in scale.items()},
        straightness={axis: value * UM for axis, value in bows.items()},
        travel={axis: span for axis, span in travel.items() if span is not None},
        cyclic=cyclic,
    )


def _per_axis(check: Checker, data: Any, key: str) -> dict[str, float]:
    """A mapping of X and Y to numbers."""
    values = check.mapping(data, key, set(PLANE))
    return {axis: check.number(value, f"{key}.{axis}") for axis, value in values.items()}
