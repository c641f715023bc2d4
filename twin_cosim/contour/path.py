"""The programmed path: straight lines and circular arcs in machine coordinates (m).

A path is a sequence of elements; the contour error of an actual position is its distance to
the path, the distance to the nearest point of any element. Arcs lie in the XY plane (G17) at
a constant Z. Points are (n, 3) arrays of X, Y, Z in m (Z = 0 on a machine without Z).

For a path of many elements (a CAM program of thousands of short segments) the distance is not
taken to every element from every point: points sampled densely along the path give each
position an upper bound of its distance (its nearest sample, found in a k-d tree), and only the
elements with a sample within that bound (plus the sampling step) can be nearer; the exact
distance is taken to those alone (:func:`distance_to_path`).
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
        return math.dist(self.start, self.end)

    def points(self, s: np.ndarray) -> np.ndarray:
        """Points (n, 3) in m at path lengths ``s`` (m) from the start."""
        s = np.asarray(s, dtype=np.float64)
        if self.length == 0.0:
            return np.tile(np.asarray(self.start, dtype=np.float64), (len(s), 1))
        direction = np.subtract(self.end, self.start) / self.length
        return np.asarray(self.start) + s[:, None] * direction

    def extent(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Lowest and highest X, Y, Z of the segment, m."""
        return tuple(map(min, self.start, self.end)), tuple(map(max, self.start, self.end))

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

    def extent(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Lowest and highest X, Y, Z of the arc, m: its ends and the quadrant points it
        passes."""
        sign = math.copysign(1.0, self.sweep)
        first = math.ceil(sign * self.start_angle / (math.pi / 2))
        passed = [
            sign * k * math.pi / 2
            for k in range(first, first + 5)
            if 0.0 <= sign * (sign * k * math.pi / 2 - self.start_angle) <= abs(self.sweep)
        ]
        along = np.clip((np.array(passed) - self.start_angle) * sign * self.radius, 0, self.length)
        points = self.points(np.concatenate(([0.0, self.length], along)))
        return tuple(points.min(axis=0).tolist()), tuple(points.max(axis=0).tolist())

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


SAMPLES_PER_PATH = 20_000  # the dense samples of a long path, about
DIRECT_ELEMENTS = 16  # up to this many elements, every point's distance to each is taken
NEIGHBOURS = 6  # samples looked up per point at first


def distance_to_path(elements: tuple[Element, ...], points: np.ndarray) -> np.ndarray:
    """Distance (m) of each point (n, 3) to the nearest element of the path (exact; pruned
    by a k-d tree for a path of many elements, see the module docstring)."""
    if not elements:
        raise ValueError("a path needs at least one element")
    if len(elements) <= DIRECT_ELEMENTS:
        return np.min([element.distance(points) for element in elements], axis=0)
    from scipy.spatial import cKDTree

    samples, owner, step = _dense_samples(elements)
    # every point of an element lies within half a step of one of its samples (an arc's chord
    # is shorter than its length), so the nearest point of a path at distance d from a
    # position has a sample within d + step / 2 of it: only those samples' elements can be it
    tree = cKDTree(samples)
    nearest, found = tree.query(points, k=NEIGHBOURS)
    reach = nearest[:, 0] + step / 2 + 1e-12
    rows = np.repeat(np.arange(len(points)), NEIGHBOURS)
    keep = (nearest <= reach[:, None]).ravel()
    element, rows = owner[found.ravel()[keep]], rows[keep]
    more = np.flatnonzero(nearest[:, -1] <= reach)  # may have more samples in reach
    if len(more):
        extra = tree.query_ball_point(points[more], reach[more], return_sorted=False)
        sizes = np.fromiter((len(f) for f in extra), dtype=np.intp, count=len(extra))
        flat = np.fromiter((i for f in extra for i in f), dtype=np.intp, count=sizes.sum())
        element = np.concatenate((element, owner[flat]))
        rows = np.concatenate((rows, np.repeat(more, sizes)))
    pairs = np.unique(element * len(points) + rows)
    element, rows = np.divmod(pairs, len(points))
    distance = nearest[:, 0].copy()
    np.minimum.at(distance, rows, _pair_distances(elements, element, points[rows]))
    return distance


def _dense_samples(elements: tuple[Element, ...]) -> tuple[np.ndarray, np.ndarray, float]:
    """Points along the path (m), the element of each, and the largest spacing along an
    element (m)."""
    lengths = np.array([e.length for e in elements])
    step = max(float(lengths.sum()) / SAMPLES_PER_PATH, 1e-9)
    counts = np.maximum(np.ceil(lengths / step).astype(np.intp), 1) + 1
    owner = np.repeat(np.arange(len(elements)), counts)
    fraction = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    fraction = fraction / np.repeat(counts - 1, counts)
    samples = np.empty((len(owner), 3))
    is_line = np.array([isinstance(e, Line) for e in elements])
    lines = is_line[owner]
    starts = np.array([e.start if isinstance(e, Line) else (0.0,) * 3 for e in elements])
    ends = np.array([e.end if isinstance(e, Line) else (0.0,) * 3 for e in elements])
    a, b = starts[owner[lines]], ends[owner[lines]]
    samples[lines] = a + fraction[lines, None] * (b - a)
    for k in np.flatnonzero(~is_line):
        rows = owner == k
        samples[rows] = elements[k].points(fraction[rows] * elements[k].length)
    return samples, owner, float(np.max(lengths / (counts - 1)))


def _pair_distances(
    elements: tuple[Element, ...], element: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Distance (m) of each point (n, 3) to its element ``elements[element[k]]``, all at once."""
    distance = np.empty(len(points))
    is_line = np.array([isinstance(e, Line) for e in elements])[element]
    if is_line.any():
        chosen = element[is_line]
        starts = np.array([e.start if isinstance(e, Line) else (0, 0, 0) for e in elements])
        ends = np.array([e.end if isinstance(e, Line) else (0, 0, 0) for e in elements])
        a, span = starts[chosen], ends[chosen] - starts[chosen]
        squared = np.einsum("ij,ij->i", span, span)
        along = np.einsum("ij,ij->i", points[is_line] - a, span)
        u = np.clip(np.divide(along, squared, out=np.zeros_like(along), where=squared > 0), 0, 1)
        distance[is_line] = np.linalg.norm(points[is_line] - (a + u[:, None] * span), axis=1)
    for k in np.unique(element[~is_line]):
        rows = element == k
        distance[rows] = elements[k].distance(points[rows])
    return distance
