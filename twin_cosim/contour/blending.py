"""Corner blending: a part program's motions made into one path of segments and joins.

In exact stop (G61) every motion block is one segment and every join a stop. With blending
(G64 P<tolerance>, LinuxCNC's semantics: the path may leave a programmed corner by at most the
tolerance) a corner between two straight lines in the XY plane is rounded by an arc tangent to
both lines. For a corner whose direction turns by ``phi`` (the interior angle is
``theta = pi - phi``) the largest such arc within the tolerance ``e`` has the radius

    r = e sin(theta/2) / (1 - sin(theta/2)) = e cos(phi/2) / (1 - cos(phi/2))

(its middle lies ``r / cos(phi/2) - r`` from the corner), touching each line ``r tan(phi/2)``
from the corner; that length may take at most half of either line, so that the next corner's
arc finds its own half (a chain of short chords along an arc becomes a chain of arcs of about
the arc's radius, far inside any tolerance). The speed through a blend arc is that of an arc of
its radius (:mod:`~twin_cosim.contour.interpolation`): ``sqrt(a r)`` and ``(j r^2)^(1/3)`` of
the axes' acceleration and jerk (:func:`corner_speed`).

Joins that stay are either tangent (a line into an arc, an arc into a blend, collinear lines) or
a kink (a corner with an arc or with a Z move, which is not rounded). Each join has the step of
the unit direction ``du`` and of the curvature vector ``d(kappa n)`` (1/m) across it; the planner
lets the path pass a join at the speed ``v`` whose steps stay within each axis' jerk over one
interpolation period ``T`` (the references are sampled at it): ``v |du_i| <= j_i T^2`` and
``v |du_i| <= a_i T`` (a velocity step) and ``v^2 |d(kappa n)_i| <= j_i T`` (an acceleration
step, as where a line meets an arc) for every axis ``i``. A kink at a real corner so passes at
almost zero speed.

Before the corners are rounded, LinuxCNC's naive CAM detector (G64's Q, P when Q is not given)
merges consecutive straight moves in the XY plane at one feed whose corners all lie within Q of
the straight line from the first one's start to the last one's end into that line
(:func:`merge_straight`): a CAM program's chords of a curve, whose end points are rounded to
the program's digits (0.1 um steps on chords of a few um turn the direction back and forth),
become fewer, longer lines whose corners blend into arcs of about the curve's radius.

The segments are arrays (:class:`Segments`): a program of thousands of blocks is blended,
limited and sampled without a Python step per block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from twin_cosim.contour.path import Arc, Element, Line
from twin_cosim.scenario.machine import AxisLimits

ARC_SHARE = 0.5  # share rho of the axes' acceleration and jerk kept for an arc's centripetal terms
TANGENT_ANGLE = 1e-9  # rad: joins turning less are tangent (rounding of the program's numbers)
REVERSAL_ANGLE = math.pi - 1e-6  # rad: a line that turns back on itself stops
COORDINATE = {"X": 0, "Y": 1, "Z": 2}
MERGE_WINDOW = 16  # blocks: the first window of candidate ends of a merged line


@dataclass(frozen=True)
class Segments:
    """Pieces of a path as arrays (n segments): programmed elements, the parts of lines left
    between blends, and blend arcs.

    Attributes
    ----------
    is_line : numpy.ndarray
        True for a line, False for an arc.
    start, end : numpy.ndarray
        A line's ends, (n, 3) m.
    centre : numpy.ndarray
        An arc's centre X, Y and its height Z, (n, 3) m.
    radius, angle, sweep : numpy.ndarray
        An arc's radius (m), start angle and swept angle (rad, > 0 counter-clockwise).
    feed : numpy.ndarray
        Programmed path speed, m/s; NaN for a rapid traverse (a blend takes the slower of the
        two blocks it joins).
    block : numpy.ndarray
        Index of the motion block each belongs to (a blend: the block whose end it rounds).
    """

    is_line: np.ndarray
    start: np.ndarray
    end: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    angle: np.ndarray
    sweep: np.ndarray
    feed: np.ndarray
    block: np.ndarray

    @classmethod
    def of(cls, elements: list[Element], feeds: list[float | None]) -> Segments:
        """The segments of elements (one block each), with their feeds (m/s, None: rapid)."""
        n = len(elements)
        is_line = np.array([isinstance(e, Line) for e in elements], dtype=bool)
        start, end, centre = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        radius, angle, sweep = np.ones(n), np.zeros(n), np.zeros(n)
        for k, e in enumerate(elements):
            if isinstance(e, Line):
                start[k], end[k] = e.start, e.end
            else:
                centre[k] = (e.centre[0], e.centre[1], e.z)
                radius[k], angle[k], sweep[k] = e.radius, e.start_angle, e.sweep
        feed = np.array([np.nan if f is None else f for f in feeds], dtype=np.float64)
        return cls(is_line, start, end, centre, radius, angle, sweep, feed, np.arange(n))

    def __len__(self) -> int:
        return len(self.is_line)

    @property
    def lengths(self) -> np.ndarray:
        """Length of each segment, m."""
        line = np.linalg.norm(self.end - self.start, axis=1)
        return np.where(self.is_line, line, self.radius * np.abs(self.sweep))

    @property
    def direction(self) -> np.ndarray:
        """A line's unit direction, (n, 3) (0 for an arc)."""
        span = self.end - self.start
        norm = np.linalg.norm(span, axis=1)
        safe = np.where(norm > 0, norm, 1.0)
        return np.where(self.is_line[:, None], span / safe[:, None], 0.0)

    def element(self, k: int) -> Element:
        """Segment ``k`` as a path element."""
        if self.is_line[k]:
            return Line(tuple(self.start[k].tolist()), tuple(self.end[k].tolist()))
        return Arc(
            (float(self.centre[k, 0]), float(self.centre[k, 1])),
            float(self.radius[k]),
            float(self.angle[k]),
            float(self.sweep[k]),
            float(self.centre[k, 2]),
        )

    def _phi(self, index: np.ndarray, local: np.ndarray) -> np.ndarray:
        return self.angle[index] + np.sign(self.sweep[index]) * local / self.radius[index]

    def tangent(self, index: np.ndarray, local: np.ndarray) -> np.ndarray:
        """Unit tangents (m, 3) at ``local`` (m) into segments ``index``."""
        phi = self._phi(index, local)
        arc = np.sign(self.sweep[index])[:, None] * np.column_stack(
            (-np.sin(phi), np.cos(phi), np.zeros_like(phi))
        )
        return np.where(self.is_line[index, None], self.direction[index], arc)

    def curvature(self, index: np.ndarray, local: np.ndarray) -> np.ndarray:
        """Curvature vectors kappa n (1/m, (m, 3)) at ``local`` (m) into segments ``index``: 0
        on a line, 1/R towards the centre on an arc."""
        phi = self._phi(index, local)
        arc = -np.column_stack((np.cos(phi), np.sin(phi), np.zeros_like(phi)))
        return np.where(self.is_line[index, None], 0.0, arc / self.radius[index, None])

    def points(self, index: np.ndarray, local: np.ndarray) -> np.ndarray:
        """Points (m, 3) in m at ``local`` (m) into segments ``index``."""
        phi = self._phi(index, local)
        arc = self.centre[index] + self.radius[index, None] * np.column_stack(
            (np.cos(phi), np.sin(phi), np.zeros_like(phi))
        )
        on_line = self.start[index] + local[:, None] * self.direction[index]
        return np.where(self.is_line[index, None], on_line, arc)

    def derivatives(
        self, index: np.ndarray, local: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray
    ) -> np.ndarray:
        """Velocity, acceleration and jerk of X, Y, Z, shape (3 quantities, m, 3), at path
        speed ``v`` (m/s), acceleration ``a`` (m/s^2) and jerk ``j`` (m/s^3) at ``local`` (m)
        into segments ``index``."""
        tangent = self.tangent(index, local)
        bend = self.curvature(index, local)  # kappa n
        kappa = np.where(self.is_line[index], 0.0, 1.0 / self.radius[index])
        velocity = v[:, None] * tangent
        acceleration = a[:, None] * tangent + (v**2)[:, None] * bend
        jerk = (j - v**3 * kappa**2)[:, None] * tangent + (3 * v * a)[:, None] * bend
        return np.stack([velocity, acceleration, jerk])

    def path_limits(self, limits: dict[str, AxisLimits]) -> np.ndarray:
        """Each segment's path speed, acceleration and jerk limits (m/s, m/s^2, m/s^3), shape
        (n, 3), from every axis' limits and its feed.

        A line with unit direction u: each limit = min over axes of (axis limit / |u_i|); an
        arc: a constant speed min(v_axis, sqrt(rho a R), (rho j R^2)^(1/3)), the share rho of
        the axes' acceleration and jerk kept for the centripetal terms, the rest for the ramps.
        """
        u = np.abs(self.direction)
        out = np.empty((len(self), 3))
        for q, quantity in enumerate(("velocity", "acceleration", "jerk")):
            bound = np.full(len(self), np.inf)
            for name, lim in limits.items():
                share = u[:, COORDINATE[name]]
                with np.errstate(divide="ignore"):
                    bound = np.minimum(
                        bound, np.where(share > 0, getattr(lim, quantity) / share, np.inf)
                    )
            out[:, q] = bound
        plane = [limits[name] for name in ("X", "Y")]
        v_axis = min(lim.velocity for lim in plane)
        a_axis = min(lim.acceleration for lim in plane)
        j_axis = min(lim.jerk for lim in plane)
        arc_speed = np.minimum(
            v_axis,
            np.minimum(
                np.sqrt(ARC_SHARE * a_axis * self.radius),
                np.cbrt(ARC_SHARE * j_axis * self.radius**2),
            ),
        )
        arc = ~self.is_line
        out[arc] = np.column_stack(
            (
                arc_speed,
                np.full(len(self), (1 - ARC_SHARE) * a_axis),
                np.full(len(self), (1 - ARC_SHARE) * j_axis),
            )
        )[arc]
        out[:, 0] = np.fmin(out[:, 0], self.feed)
        return out


@dataclass(frozen=True)
class Joins:
    """Where each segment meets the next (n - 1 joins of n segments).

    Attributes
    ----------
    stop : numpy.ndarray
        The path stops here (exact stop, a line that turns back).
    direction_step : numpy.ndarray
        Step of the unit tangent across each join, (m, 3) (0 where tangent).
    curvature_step : numpy.ndarray
        Step of the curvature vector kappa n across each join, (m, 3) 1/m.
    """

    stop: np.ndarray
    direction_step: np.ndarray
    curvature_step: np.ndarray

    def speed_limits(self, limits: dict[str, AxisLimits], period: float) -> np.ndarray:
        """The speed (m/s) at which every axis' velocity and acceleration steps across each
        join stay within its jerk over one interpolation period ``period`` (s) (module
        docstring); 0 at a stop."""
        speed = np.full(len(self.stop), np.inf)
        with np.errstate(divide="ignore"):
            for name, lim in limits.items():
                du = np.abs(self.direction_step[:, COORDINATE[name]])
                dk = np.abs(self.curvature_step[:, COORDINATE[name]])
                by_step = np.minimum(lim.jerk * period**2, lim.acceleration * period) / du
                speed = np.minimum(speed, by_step)
                speed = np.minimum(speed, np.sqrt(lim.jerk * period / dk))
        return np.where(self.stop, 0.0, speed)


def blend_radius(turn: np.ndarray, tolerance: np.ndarray, room: np.ndarray) -> np.ndarray:
    """The radius (m) of the arc that rounds a corner between two lines.

    Parameters
    ----------
    turn
        Angle the direction turns by at the corner, rad (0 < turn < pi; the interior angle is
        pi - turn).
    tolerance
        Largest distance of the arc from the corner, m (``inf``: no bound).
    room
        Largest distance from the corner at which the arc may touch either line, m.
    """
    half = np.asarray(turn, dtype=np.float64) / 2
    by_room = room / np.tan(half)
    with np.errstate(invalid="ignore"):  # inf * 0 where a bound is missing
        by_tolerance = tolerance * np.cos(half) / (2.0 * np.sin(half / 2) ** 2)  # 1 - cos
    return np.fmin(by_tolerance, by_room)


def corner_speed(
    turn: float, tolerance: float, room: float, limits: dict[str, AxisLimits]
) -> float:
    """The highest speed (m/s) through the blend arc of a corner in the XY plane: that of an
    arc of its radius r (:func:`blend_radius`), min(v_axis, sqrt(rho a r), (rho j r^2)^(1/3))
    with the axes' least velocity, acceleration and jerk limits.

    Parameters
    ----------
    turn, tolerance, room
        As for :func:`blend_radius` (rad, m, m).
    limits
        Each axis' limits by name (X and Y at least).
    """
    radius = float(blend_radius(np.array([turn]), np.array([tolerance]), np.array([room]))[0])
    arc = Arc((0.0, 0.0), radius, 0.0, turn)
    segments = Segments.of([arc], [None])
    return float(segments.path_limits(limits)[0, 0])


def merge_straight(
    segments: Segments, mergeable: np.ndarray, tolerance: np.ndarray
) -> tuple[Segments, np.ndarray]:
    """Merge runs of straight moves whose corners lie within ``tolerance`` of one line.

    Parameters
    ----------
    segments
        Consecutive motion blocks, one segment each.
    mergeable
        Per join (n - 1): the blocks on either side may merge (both lines in the XY plane, one
        feed, both blended with the same ``tolerance``).
    tolerance
        Per block: how far a corner may lie from the merged line, m (G64's Q; 0: no merging).

    Returns
    -------
    tuple
        The merged segments (each merged line keeps its first block's feed and index), and for
        each the index of the last block it covers (it starts at the one after the previous
        one's).
    """
    n = len(segments)
    stops = np.append(np.flatnonzero(~np.asarray(mergeable, dtype=bool)), n - 1)
    last = []
    first = 0
    while first < n:
        reach = int(stops[np.searchsorted(stops, first)])  # the last block a chain may reach
        end = _merged_end(segments, first, reach, tolerance[first]) if reach > first else first
        last.append(end)
        first = end + 1
    last_block = np.array(last)
    first_block = np.concatenate(([0], last_block[:-1] + 1))
    merged = Segments(
        is_line=segments.is_line[first_block],
        start=segments.start[first_block],
        end=np.where(segments.is_line[first_block, None], segments.end[last_block], 0.0),
        centre=segments.centre[first_block],
        radius=segments.radius[first_block],
        angle=segments.angle[first_block],
        sweep=segments.sweep[first_block],
        feed=segments.feed[first_block],
        block=segments.block[first_block],
    )
    return merged, last_block


def _merged_end(segments: Segments, first: int, reach: int, tolerance: float) -> int:
    """The last block of the line merged from block ``first`` (at most ``reach``): the first
    ``end`` whose next block would leave a corner beyond ``tolerance`` (m) of the line from
    ``first``'s start to that block's end. Candidate ends are tried in windows that double, all
    of a window at once."""
    if tolerance <= 0:
        return first
    a = segments.start[first]
    end, window = first, MERGE_WINDOW
    while end < reach:
        ends = np.arange(end + 1, min(end + window, reach) + 1)  # candidate last blocks
        corners = segments.end[first : ends[-1]] - a  # each block's end, from first's start
        span = segments.end[ends] - a
        squared = np.einsum("ij,ij->i", span, span)
        along = np.zeros((len(corners), len(ends)))
        np.divide(corners @ span.T, squared, out=along, where=squared > 0)
        np.clip(along, 0.0, 1.0, out=along)
        offset = corners[:, None, :] - along[:, :, None] * span[None, :, :]
        away = np.einsum("kmi,kmi->km", offset, offset) > tolerance**2
        away &= np.arange(first, ends[-1])[:, None] < ends[None, :]  # the corners before each
        beyond = away.any(axis=0)
        if beyond.any():
            return int(ends[np.argmax(beyond)]) - 1
        end, window = int(ends[-1]), 2 * window
    return end


def blend(segments: Segments, blends: np.ndarray, tolerance: np.ndarray) -> tuple[Segments, Joins]:
    """Round the corners of consecutive motion blocks (one segment each, in order, each starting
    where the one before ends, none of zero length).

    Parameters
    ----------
    segments
        The blocks' elements.
    blends
        Per block: its end is blended (G64) rather than an exact stop (G61).
    tolerance
        Per block: how far the blend at its end may leave the corner, m (``inf``: no bound).

    Returns
    -------
    tuple
        The segments of the path (trimmed lines, blend arcs, arcs) and their joins.
    """
    n = len(segments)
    lengths = segments.lengths
    every = np.arange(n)
    ends_out = segments.tangent(every, lengths)[:-1]
    starts_in = segments.tangent(every, np.zeros(n))[1:]
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", ends_out, starts_in), -1.0, 1.0))
    flat = segments.is_line & (segments.start[:, 2] == segments.end[:, 2])
    can = blends[:-1] & flat[:-1] & flat[1:] & (turn > TANGENT_ANGLE) & (turn < REVERSAL_ANGLE)
    room = np.minimum(lengths[:-1], lengths[1:]) / 2
    radius = np.where(can, blend_radius(np.where(can, turn, 1.0), tolerance[:-1], room), 0.0)
    can &= radius > 0
    touch = np.where(can, radius * np.tan(turn / 2), 0.0)
    corner_lines = flat[:-1] & flat[1:] & (turn > TANGENT_ANGLE)
    stop_after = ~blends[:-1] | (turn >= REVERSAL_ANGLE) | (corner_lines & ~can)
    # the lines left: each block's line without what the blends at its ends take
    cut_start = np.concatenate(([0.0], touch))
    cut_end = np.concatenate((touch, [0.0]))
    direction = segments.direction
    kept_start = segments.start + cut_start[:, None] * direction
    kept_end = segments.end - cut_end[:, None] * direction
    keep = ~segments.is_line | (lengths - cut_start - cut_end > lengths * 1e-9)
    # the blend arcs at the corners
    corner = segments.end[:-1]
    left = ends_out[:, 0] * starts_in[:, 1] - ends_out[:, 1] * starts_in[:, 0] > 0
    side = np.where(left, 1.0, -1.0)
    normal = np.column_stack((-ends_out[:, 1], ends_out[:, 0], np.zeros(n - 1))) * side[:, None]
    arc_start = corner - touch[:, None] * ends_out
    centre = arc_start + radius[:, None] * normal
    centre[:, 2] = corner[:, 2]
    arc_angle = np.arctan2(arc_start[:, 1] - centre[:, 1], arc_start[:, 0] - centre[:, 0])
    feed = np.fmin(segments.feed[:-1], segments.feed[1:])
    # interleave: block k's segment at 2k, the blend at its end at 2k + 1
    order = np.arange(2 * n - 1)
    exists = np.concatenate([np.column_stack((keep[:-1], can)).ravel(), keep[-1:]])
    is_block = order % 2 == 0

    def pick(block_values, blend_values):
        out = np.empty((2 * n - 1,) + block_values.shape[1:], dtype=block_values.dtype)
        out[is_block] = block_values
        out[~is_block] = blend_values
        return out[exists]

    result = Segments(
        is_line=pick(segments.is_line, np.zeros(n - 1, dtype=bool)),
        start=pick(np.where(segments.is_line[:, None], kept_start, 0.0), np.zeros((n - 1, 3))),
        end=pick(np.where(segments.is_line[:, None], kept_end, 0.0), np.zeros((n - 1, 3))),
        centre=pick(segments.centre, centre),
        radius=pick(segments.radius, np.where(can, radius, 1.0)),
        angle=pick(segments.angle, arc_angle),
        sweep=pick(segments.sweep, side * turn),
        feed=pick(segments.feed, feed),
        block=pick(segments.block, segments.block[:-1]),
    )
    # a stop after a block's own segment where it ends in one (a blend after it: no stop)
    stops = pick(np.concatenate((stop_after, [False])), np.zeros(n - 1, dtype=bool))[:-1]
    count = len(result)
    ends = result.lengths
    before, after = np.arange(count - 1), np.arange(1, count)
    joins = Joins(
        stop=stops,
        direction_step=result.tangent(after, np.zeros(count - 1))
        - result.tangent(before, ends[:-1]),
        curvature_step=result.curvature(after, np.zeros(count - 1))
        - result.curvature(before, ends[:-1]),
    )
    return result, joins


def concatenate(parts: list[Segments]) -> Segments:
    """The segments of several runs of a path, one after the other (block indices kept)."""
    names = ("is_line", "start", "end", "centre", "radius", "angle", "sweep", "feed", "block")
    return Segments(*(np.concatenate([getattr(p, name) for p in parts]) for name in names))
