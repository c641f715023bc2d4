"""The programmed path: straight lines and circular arcs in machine coordinates (m).

A path is a sequence of elements; the contour error of an actual position is its distance to
the path, the distance to the nearest point of any element. Arcs lie in the XY plane (G17) at
a constant Z. Points are (n, 3) arrays of X, Y, Z in m (Z = 0 on a machine without Z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Line:
    """A straight line from ``start`` to ``end`` (m, X Y Z)."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]

    @property
    def length(self) -> float:
        """Length, m."""
        return float(np.linalg.norm(np.subtract(self.end, self.start)))

    def points(self, s: np.ndarray) -> np.ndarray:
        """Points (n, 3) in m at path lengths ``s`` (m) from the start."""
        s = np.asarray(s, dtype=np.float64)
        if self.length == 0.0:
            return np.tile(np.asarray(self.start, dtype=np.float64), (len(s), 1))
        direction = np.subtract(self.end, self.start) / self.length
        return np.asarray(self.start) + s[:, None] * direction

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance (m) of each point (n, 3) to the line segment."""
        a, b = np.asarray(self.start), np.asarray(self.end)
        span = b - a
        squared = float(span @ span)
        if squared == 0.0:
            return np.linalg.norm(points - a, axis=1)
        u = np.clip((points - a) @ span / squared, 0.0, 1.0)
        return np.linalg.norm(points - (a + u[:, None] * span), axis=1)


@dataclass(frozen=True)
class Arc:
    """A circular arc in the XY plane (G17) at height ``z``.

    Attributes
    ----------
    centre : tuple
        Centre X, Y in m.
    radius : float
        Radius, m (> 0).
    start_angle : float
        Angle of the start point from +X, rad.
    sweep : float
        Swept angle, rad: > 0 counter-clockwise (G03), < 0 clockwise (G02), seen from +Z; may
        exceed one turn.
    z : float
        Height, m.
    """

    centre: tuple[float, float]
    radius: float
    start_angle: float
    sweep: float
    z: float = 0.0

    @property
    def length(self) -> float:
        """Length, m."""
        return self.radius * abs(self.sweep)

    def angles(self, s: np.ndarray) -> np.ndarray:
        """Angles (rad) at path lengths ``s`` (m) from the start."""
        return self.start_angle + math.copysign(1.0, self.sweep) * np.asarray(s) / self.radius

    def points(self, s: np.ndarray) -> np.ndarray:
        """Points (n, 3) in m at path lengths ``s`` (m) from the start."""
        angle = self.angles(s)
        return np.column_stack(
            (
                self.centre[0] + self.radius * np.cos(angle),
                self.centre[1] + self.radius * np.sin(angle),
                np.full(len(angle), self.z),
            )
        )

    @property
    def end(self) -> tuple[float, float, float]:
        """End point, m."""
        return tuple(float(v) for v in self.points(np.array([self.length]))[0])

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance (m) of each point (n, 3) to the arc."""
        dx = points[:, 0] - self.centre[0]
        dy = points[:, 1] - self.centre[1]
        dz = points[:, 2] - self.z
        radial = np.hypot(np.hypot(dx, dy) - self.radius, dz)
        if abs(self.sweep) >= 2 * math.pi:
            return radial
        # inside the arc's angular span: the radial distance; else the nearer end point
        offset = np.mod(
            math.copysign(1.0, self.sweep) * (np.arctan2(dy, dx) - self.start_angle), 2 * math.pi
        )
        ends = self.points(np.array([0.0, self.length]))
        to_ends = np.minimum(
            np.linalg.norm(points - ends[0], axis=1), np.linalg.norm(points - ends[1], axis=1)
        )
        return np.where(offset <= abs(self.sweep), radial, to_ends)


Element = Line | Arc


def distance_to_path(elements: tuple[Element, ...], points: np.ndarray) -> np.ndarray:
    """Distance (m) of each point (n, 3) to the nearest element of the path."""
    if not elements:
        raise ValueError("a path needs at least one element")
    return np.min([element.distance(points) for element in elements], axis=0)
