"""The CNC's interpolator: path blocks to per-axis position references every 4 ms.

The blocks become segments and joins (:mod:`~twin_cosim.contour.blending`: exact stop, or
corners rounded within G64's tolerance). Each segment has a path speed limit from the
programmed feed (times the feed override) and every axis' velocity, acceleration and jerk limits:

- a line with unit direction u: path limit = min over axes of (axis limit / |u_i|), so that
  every axis keeps within its own limit; G00 runs at that speed, G01 at min(F, it);
- an arc of radius R: a constant path speed v where the limits allow,
  v = min(F, v_axis, sqrt(rho a_axis R), (rho j_axis R^2)^(1/3)) with rho = 1/2 of the axes'
  acceleration and jerk kept for the centripetal terms (v^2/R, v^3/R^2), the rest for the
  tangential ramps.

Segments whose joins do not limit the speed and whose limits are alike form a *span*: one
jerk-limited profile s(t) of ruckig (time-optimal under limits on ds/dt, d2s/dt2, d3s/dt3) from
its entry speed to its exit speed, both at zero path acceleration. The speeds at the spans'
ends come from a backward and a forward pass (the speed from which the next end's speed is
reached within the span at its acceleration and jerk, :func:`reachable_speed`), the stops (an
exact stop, a dwell, the program's end) at zero; the look-ahead caps every segment's speed so
that the machine could stop within the blocks it looks ahead. In exact stop every block is its
own span, from rest to rest, as it always was.

Every planned span is checked on a fine time grid against each axis' limits (from the exact
derivatives of its elements' geometry); a span that exceeds one is planned again slower. Dwells
hold the position. The samples are taken every ``sample_period`` (the interpolation period);
the position loop interpolates them (:func:`twin_cosim.reference.interpolate`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from twin_cosim.contour.blending import (
    ARC_SHARE,
    COORDINATE,
    Joins,
    Segments,
    blend,
    concatenate,
    merge_straight,
)
from twin_cosim.contour.gcode import Motion, Pause, Program
from twin_cosim.contour.path import Element, Line
from twin_cosim.scenario.machine import EXACT_STOP, LOOK_AHEAD, AxisLimits, PathControl

_CHECK_STEP = 2.5e-4  # s: time step of the limit check
_LIMIT_SLACK = 1e-6  # relative excess tolerated by the check (rounding)
_MAX_REPLANS = 40


class InterpolationError(ValueError):
    """A block cannot be planned within the axes' limits."""


@dataclass(frozen=True)
class Profile:
    """A jerk-limited profile s(t) of one span (ruckig's seven phases), at zero path
    acceleration where it starts and ends.

    Attributes
    ----------
    starts : numpy.ndarray
        Start time of each phase, s (from the span's start).
    p, v, a, j : numpy.ndarray
        Path position (m), speed (m/s), acceleration (m/s^2) at each phase's start, and the
        phase's jerk (m/s^3).
    duration : float
        Length of the span, s.
    """

    starts: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray
    j: np.ndarray
    duration: float

    def evaluate(self, tau: np.ndarray) -> tuple[np.ndarray, ...]:
        """(s m, ds/dt m/s, d2s/dt2 m/s^2, d3s/dt3 m/s^3) at block times ``tau`` (s)."""
        tau = np.clip(np.asarray(tau, dtype=np.float64), 0.0, self.duration)
        k = np.clip(np.searchsorted(self.starts, tau, side="right") - 1, 0, len(self.j) - 1)
        d = tau - self.starts[k]
        j = self.j[k]
        a = self.a[k] + j * d
        v = self.v[k] + self.a[k] * d + j * d**2 / 2
        s = self.p[k] + self.v[k] * d + self.a[k] * d**2 / 2 + j * d**3 / 6
        return s, v, a, j


def jerk_limited(
    length: float,
    speed: float,
    acceleration: float,
    jerk: float,
    entry: float = 0.0,
    exit: float = 0.0,
) -> Profile:
    """The time-optimal profile over ``length`` (m) from the path speed ``entry`` to ``exit``
    (m/s; at rest by default) under the path limits ``speed`` (m/s), ``acceleration``
    (m/s^2), ``jerk`` (m/s^3), from ruckig."""
    given = InputParameter(1)
    given.current_position = [0.0]
    given.target_position = [float(length)]
    if entry or exit:
        given.current_velocity = [float(entry)]
        given.target_velocity = [float(exit)]
    given.max_velocity = [float(speed)]
    given.max_acceleration = [float(acceleration)]
    given.max_jerk = [float(jerk)]
    trajectory = Trajectory(1)
    result = Ruckig(1).calculate(given, trajectory)
    if result != Result.Working:
        raise InterpolationError(
            f"ruckig cannot plan {length:g} m from {entry:g} to {exit:g} m/s at {speed:g} m/s, "
            f"{acceleration:g} m/s^2, {jerk:g} m/s^3: {result}"
        )
    phases = trajectory.profiles[0][0]
    durations = np.asarray(phases.t, dtype=np.float64)
    return Profile(
        starts=np.concatenate(([0.0], np.cumsum(durations)[:-1])),
        p=np.asarray(phases.p[:7], dtype=np.float64),
        v=np.asarray(phases.v[:7], dtype=np.float64),
        a=np.asarray(phases.a[:7], dtype=np.float64),
        j=np.asarray(phases.j, dtype=np.float64),
        duration=float(trajectory.duration),
    )


def axis_derivatives(element: Element, profile: Profile, tau: np.ndarray) -> np.ndarray:
    """Velocity, acceleration and jerk of X, Y, Z along a block: shape (3 quantities, n, 3)."""
    s, v, a, j = profile.evaluate(tau)
    index = np.zeros(len(s), dtype=np.intp)
    return Segments.of([element], [None]).derivatives(index, s, v, a, j)


def first_limits(
    element: Element, feed: float | None, limits: dict[str, AxisLimits]
) -> tuple[float, float, float]:
    """Path speed, acceleration and jerk limits of a block before the check (m/s, m/s^2, m/s^3)."""
    speed, acceleration, jerk = Segments.of([element], [feed]).path_limits(limits)[0]
    return float(speed), float(acceleration), float(jerk)


def _worst_excess(element: Element, profile: Profile, limits: dict[str, AxisLimits]) -> float:
    """Largest ratio of an axis' |velocity|, |acceleration| or |jerk| to its limit."""
    tau = np.linspace(0.0, profile.duration, max(int(profile.duration / _CHECK_STEP), 2) + 1)
    tau = np.union1d(tau, np.clip(profile.starts, 0.0, profile.duration))
    derivatives = np.abs(axis_derivatives(element, profile, tau))
    worst = 0.0
    for name, lim in limits.items():
        column = COORDINATE[name]
        caps = (lim.velocity, lim.acceleration, lim.jerk)
        for q, cap in enumerate(caps):
            worst = max(worst, float(derivatives[q, :, column].max()) / cap)
    return worst


def plan_block(
    element: Element, feed: float | None, limits: dict[str, AxisLimits], line: int = 0
) -> Profile:
    """The profile of one motion block within every axis' limits.

    Parameters
    ----------
    element
        The block's geometry (m).
    feed
        Programmed path speed, m/s; None for a rapid traverse.
    limits
        Each axis' limits by name.
    line
        The program line, named in errors.
    """
    speed, acceleration, jerk = first_limits(element, feed, limits)
    for _ in range(_MAX_REPLANS):
        profile = jerk_limited(element.length, speed, acceleration, jerk)
        excess = _worst_excess(element, profile, limits)
        if excess <= 1 + _LIMIT_SLACK:
            return profile
        shrink = max(0.5, min(0.95, 1 / excess))
        speed, acceleration, jerk = speed * shrink, acceleration * shrink, jerk * shrink
    raise InterpolationError(f"line {line}: no profile within the axes' limits was found")


MERGE_RATIO = 0.95  # segments whose speed limits lie within this ratio share a span
PASS_MARGIN = 1e-6  # share of a span's length kept back in the passes (ruckig's rounding)
SHORT_SPAN = 1e-6  # m: a span this short keeps its speed (a change would be below rounding)
FEED_SHORTFALL = 1e-3  # a stretch whose top speed falls this share short of its feed is reported


def ramp_distance(start: float, end: float, acceleration: float, jerk: float) -> float:
    """Path length (m) of the shortest jerk-limited change of speed from ``start`` to ``end``
    (m/s), at zero acceleration before and after, under ``acceleration`` (m/s^2) and ``jerk``
    (m/s^3): the profile is symmetric, so the length is the mean speed times the time."""
    change = abs(end - start)
    if change <= acceleration**2 / jerk:
        duration = 2.0 * math.sqrt(change / jerk)
    else:
        duration = change / acceleration + acceleration / jerk
    return (start + end) / 2.0 * duration


def reachable_speed(end, length, acceleration: float, jerk: float):
    """The highest speed (m/s) from which ``end`` (m/s) is reached within ``length`` (m) (the
    inverse of :func:`ramp_distance` in its start speed; also the highest speed reached from
    ``end``, the profile being symmetric); numbers or arrays."""
    end = np.asarray(end, dtype=np.float64)
    length = np.maximum(np.asarray(length, dtype=np.float64), 0.0)
    knee = acceleration**2 / jerk  # the largest change without a phase at full acceleration
    with np.errstate(invalid="ignore"):  # an infinite length: any speed
        # a change x^2 within the knee: x^3 + 2 end x = length sqrt(jerk), Cardano's real root
        q = length * math.sqrt(jerk)
        root = np.sqrt(q**2 / 4.0 + (2.0 * end) ** 3 / 27.0)
        x = np.cbrt(q / 2.0 + root) + np.cbrt(q / 2.0 - root)
        # a larger change: change^2 + b change + c = 0
        b = knee + 2.0 * end
        c = 2.0 * end * knee - 2.0 * length * acceleration
        beyond = (-b + np.sqrt(np.maximum(b * b - 4.0 * c, 0.0))) / 2.0
    change = np.where(length <= (2.0 * end + knee) * acceleration / jerk, x * x, beyond)
    speed = np.where(np.isinf(length), np.inf, end + change)
    return float(speed) if speed.ndim == 0 else speed


def cap_reason(element: Element, limits: dict[str, AxisLimits]) -> str:
    """What sets the highest path speed the axes' limits allow on an element, for a reader."""
    if isinstance(element, Line):
        u = np.abs(np.subtract(element.end, element.start)) / element.length
        axis = min(
            (name for name in limits if u[COORDINATE[name]] > 0),
            key=lambda name: limits[name].velocity / u[COORDINATE[name]],
        )
        return f"axis {axis}'s velocity limit"
    plane = [limits[name] for name in ("X", "Y")]
    radius = element.radius
    bounds = {
        "the axes' velocity limit": min(lim.velocity for lim in plane),
        "the centripetal acceleration": math.sqrt(
            ARC_SHARE * min(lim.acceleration for lim in plane) * radius
        ),
        "the jerk": math.cbrt(ARC_SHARE * min(lim.jerk for lim in plane) * radius**2),
    }
    return f"{min(bounds, key=bounds.__getitem__)} on radius {radius * 1e3:g} mm"


@dataclass
class _Span:
    """Segments traversed by one profile (indices ``first`` to ``last`` of the run)."""

    first: int
    last: int
    speed: float
    acceleration: float
    jerk: float
    length: float
    top: float  # the highest speed limit of its segments, m/s
    entry: float = 0.0
    exit: float = 0.0
    profile: Profile | None = None
    planned_for: tuple = ()


def _spans(
    segments: Segments,
    joins: Joins,
    limits: dict[str, AxisLimits],
    period: float,
    look_ahead: int,
) -> tuple[list[_Span], list[float]]:
    """The spans of a run's segments and the highest speed (m/s) at each span boundary (0 at
    the run's ends and at stops).

    A segment's limits in a span are its block's (:meth:`Segments.path_limits`); on an arc the
    tangential acceleration is also kept so that its part of the jerk across the path
    (3 v a / R) stays within the share of the jerk left from the centripetal term; its speed is
    one from which the machine stops within the blocks it looks ahead (from the segment's
    start) at the run's least acceleration and jerk, where they end before the run does.
    """
    lengths = segments.lengths
    ends = np.cumsum(lengths)
    blocks = segments.block - segments.block[0]
    block_end = np.zeros(blocks[-1] + 1)
    np.maximum.at(block_end, blocks, ends)
    block_end = np.maximum.accumulate(block_end)
    window = np.minimum(blocks + look_ahead, len(block_end) - 1)
    ahead = np.where(  # the run's end is a stop the passes plan for exactly
        window < len(block_end) - 1, block_end[window] - ends, np.inf
    )
    bounds = segments.path_limits(limits)
    least = (float(bounds[:, 1].min()), float(bounds[:, 2].min()))
    lone = bool(joins.stop.all())
    if not lone:
        arc = ~segments.is_line
        bounds[arc, 1] = np.minimum(
            bounds[arc, 1], bounds[arc, 2] * segments.radius[arc] / (3.0 * bounds[arc, 0])
        )
        bounds[:, 0] = np.minimum(bounds[:, 0], reachable_speed(0.0, ahead + lengths, *least))
        stop_at_end = reachable_speed(0.0, ahead, *least).tolist()
    join_speed = joins.speed_limits(limits, period).tolist()
    spans: list[_Span] = []
    caps = [0.0]
    rows = bounds.tolist()
    sizes = lengths.tolist()
    for k, (speed, acceleration, jerk) in enumerate(rows):
        if k > 0 and not lone and join_speed[k - 1] > 0.0:
            span = spans[-1]
            merged = min(span.speed, speed)
            if join_speed[k - 1] >= merged and max(span.top, speed) * MERGE_RATIO <= merged:
                span.last, span.speed, span.top = k, merged, max(span.top, speed)
                span.acceleration = min(span.acceleration, acceleration)
                span.jerk = min(span.jerk, jerk)
                span.length += sizes[k]
                continue
            caps.append(min(join_speed[k - 1], span.speed, speed, stop_at_end[k - 1]))
        elif k > 0:
            caps.append(0.0)
        spans.append(_Span(k, k, speed, acceleration, jerk, sizes[k], speed))
    caps.append(0.0)
    return spans, caps


def _passes(spans: list[_Span], caps: list[float]) -> None:
    """Each span's entry and exit speed (m/s): the boundaries' caps lowered by a backward and a
    forward pass so that every span can change between them within its length (a span shorter
    than :data:`SHORT_SPAN` keeps its speed)."""
    speed = list(caps)

    def reach(span: _Span, other: float) -> float:
        if span.length < SHORT_SPAN:
            return other
        length = span.length * (1 - PASS_MARGIN)
        return reachable_speed(other, length, span.acceleration, span.jerk)

    for i in range(len(spans) - 1, -1, -1):
        speed[i] = min(speed[i], spans[i].speed, reach(spans[i], speed[i + 1]))
    for i, span in enumerate(spans):
        speed[i + 1] = min(speed[i + 1], span.speed, reach(span, speed[i]))
    for i, span in enumerate(spans):
        span.entry, span.exit = speed[i], speed[i + 1]


def _evaluate(profiles: list[Profile | None], owner: np.ndarray, tau: np.ndarray):
    """(s m, ds/dt m/s, d2s/dt2 m/s^2, d3s/dt3 m/s^3) of many profiles at once: sample k of
    ``profiles[owner[k]]`` at its time ``tau[k]`` (s); a None profile stands still at 0."""
    rows = [
        (p.starts, p.p, p.v, p.a, p.j, p.duration) if p is not None else _STILL for p in profiles
    ]
    starts, p, v, a, j, duration = (np.array(column) for column in zip(*rows, strict=True))
    tau = np.clip(tau, 0.0, duration[owner])
    phase = np.clip((starts[owner] <= tau[:, None]).sum(axis=1) - 1, 0, 6)
    d = tau - starts[owner, phase]
    p0, v0, a0, j0 = p[owner, phase], v[owner, phase], a[owner, phase], j[owner, phase]
    return (
        p0 + v0 * d + a0 * d**2 / 2 + j0 * d**3 / 6,
        v0 + a0 * d + j0 * d**2 / 2,
        a0 + j0 * d,
        j0,
    )


_STILL = (np.zeros(7), np.zeros(7), np.zeros(7), np.zeros(7), np.zeros(7), 0.0)


def _check_spans(
    spans: list[_Span], segments: Segments, limits: dict[str, AxisLimits]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The largest ratio of an axis' |velocity|, |acceleration| or |jerk| to its limit in each
    span, and the check's samples' segments and path speeds (m/s); each span is checked at its
    phases' starts and on a grid of :data:`_CHECK_STEP` (as :func:`plan_block` checks a
    block)."""
    taus, owners = [], []
    for i, span in enumerate(spans):
        profile = span.profile
        tau = np.linspace(0.0, profile.duration, max(int(profile.duration / _CHECK_STEP), 2) + 1)
        taus.append(np.union1d(tau, np.clip(profile.starts, 0.0, profile.duration)))
        owners.append(np.full(len(taus[-1]), i))
    excess = np.zeros(len(spans))
    owner = np.concatenate(owners)
    s, v, a, j = _evaluate([span.profile for span in spans], owner, np.concatenate(taus))
    starts = np.concatenate(([0.0], np.cumsum(segments.lengths)[:-1]))
    firsts = np.array([span.first for span in spans])[owner]
    lasts = np.array([span.last for span in spans])[owner]
    along = starts[firsts] + s
    index = np.clip(np.searchsorted(starts, along, side="right") - 1, firsts, lasts)
    local = np.clip(along - starts[index], 0.0, segments.lengths[index])
    derivatives = np.abs(segments.derivatives(index, local, v, a, j))
    ratio = np.zeros(len(owner))
    for name, lim in limits.items():
        column = COORDINATE[name]
        for q, cap in enumerate((lim.velocity, lim.acceleration, lim.jerk)):
            ratio = np.maximum(ratio, derivatives[q, :, column] / cap)
    ratio[v < -_LIMIT_SLACK * np.abs(v).max()] = 2.0  # a profile that runs back: plan it again
    np.maximum.at(excess, owner, ratio)
    return excess, index, v


def _plan_run(
    segments: Segments,
    joins: Joins,
    limits: dict[str, AxisLimits],
    period: float,
    look_ahead: int,
) -> tuple[list[_Span], np.ndarray]:
    """The planned spans of a run of segments, and the top speed (m/s) reached in each block
    of the run (by its index; 0 for a block merged into another)."""
    spans, caps = _spans(segments, joins, limits, period, look_ahead)
    blocks = segments.block - segments.block[0]
    for _ in range(_MAX_REPLANS):
        _passes(spans, caps)
        for span in spans:
            wanted = (span.speed, span.acceleration, span.jerk, span.entry, span.exit)
            if wanted != span.planned_for:
                span.profile = jerk_limited(
                    span.length, span.speed, span.acceleration, span.jerk, span.entry, span.exit
                )
                span.planned_for = wanted
        excess, index, speed = _check_spans(spans, segments, limits)
        over = np.flatnonzero(excess > 1 + _LIMIT_SLACK)
        if not len(over):
            top = np.zeros(blocks[-1] + 1)
            np.maximum.at(top, blocks[index], speed)
            return spans, top
        for i in over.tolist():
            shrink = max(0.5, min(0.95, 1 / excess[i]))
            span = spans[i]
            span.speed *= shrink
            span.acceleration *= shrink
            span.jerk *= shrink
            caps[i] = min(caps[i], span.speed)
            caps[i + 1] = min(caps[i + 1], span.speed)
    raise InterpolationError("no profile within the axes' limits was found")


@dataclass(frozen=True)
class BlockFeed:
    """The feed of one motion block: programmed, reached, and what the axes allow.

    Attributes
    ----------
    line : int
        The program line.
    programmed : float or None
        Programmed path speed (the feed override applied), m/s; None for a rapid traverse.
    reached : float
        Highest path speed planned in the block, m/s.
    cap : float
        Highest path speed the axes' limits allow on the block's element, m/s.
    cap_reason : str
        What sets ``cap`` (an axis' velocity limit, the centripetal acceleration on an arc...).
    stop_after : str or None
        How the path stops at the block's end: ``G61`` (an exact stop), ``end`` (a dwell or the
        program's end); None where it goes on into the next block.
    """

    line: int
    programmed: float | None
    reached: float
    cap: float
    cap_reason: str
    stop_after: str | None


@dataclass(frozen=True)
class PlannedMotion:
    """Per-axis position references of a path, every interpolation period.

    Attributes
    ----------
    axes : tuple of str
        Axis names, the columns of ``samples``.
    sample_period : float
        Interpolation period, s.
    samples : numpy.ndarray
        Positions (m), shape (samples, axes), at t = k * sample_period.
    elements : tuple
        The programmed path (lines and arcs, m): what the contour error is measured against
        (a blended path leaves its corners within the tolerance).
    end_time : float
        When the path ends (the settle time follows), s: the path time.
    feeds : tuple of BlockFeed
        Each motion block's programmed and reached feed, in program order.
    """

    axes: tuple[str, ...]
    sample_period: float
    samples: np.ndarray
    elements: tuple[Element, ...]
    end_time: float
    feeds: tuple[BlockFeed, ...]


def _mergeable(part: Segments, controls: list[PathControl]) -> tuple[np.ndarray, np.ndarray]:
    """Which neighbouring blocks the naive CAM detector may merge (both straight in the XY
    plane at one feed, blended alike), and each block's merge tolerance (m, 0: none)."""
    flat = part.is_line & (part.start[:, 2] == part.end[:, 2])
    same_feed = (part.feed[:-1] == part.feed[1:]) | (
        np.isnan(part.feed[:-1]) & np.isnan(part.feed[1:])
    )
    alike = np.array([a == b for a, b in zip(controls[:-1], controls[1:], strict=True)], dtype=bool)
    blends = np.array([c.blends for c in controls])
    mergeable = flat[:-1] & flat[1:] & same_feed & alike.reshape(-1) & blends[:-1]
    tolerance = np.array([c.merge_tolerance if c.blends else 0.0 for c in controls])
    return mergeable, tolerance


def _blend_tolerances(controls: list[PathControl], last_block: np.ndarray) -> np.ndarray:
    """How far the blend at each merged block's end may leave its corner (m): G64's P, less Q
    where a merged line (of several blocks, Q from the programmed path) meets the corner, so
    that the path stays within P."""
    merged = np.diff(last_block, prepend=-1) > 1
    near = merged | np.append(merged[1:], False)
    return np.array(
        [
            controls[k].tolerance - (controls[k].merge_tolerance if close else 0.0)
            for k, close in zip(last_block.tolist(), near.tolist(), strict=True)
        ]
    )


def _runs(blocks) -> list[list[Motion] | Pause]:
    """Motions grouped into runs between dwells; zero-length motions dropped."""
    runs: list[list[Motion] | Pause] = []
    for block in blocks:
        if isinstance(block, Pause):
            runs.append(block)
        elif block.element.length > 0.0:
            if not runs or isinstance(runs[-1], Pause):
                runs.append([])
            runs[-1].append(block)
    return runs


def plan_blocks(
    blocks: list[Motion | Pause] | tuple[Motion | Pause, ...],
    start: tuple[float, float, float],
    limits: dict[str, AxisLimits],
    sample_period: float,
    settle: float,
    path_control: PathControl = EXACT_STOP,
    look_ahead: int = LOOK_AHEAD,
    feed_override: float = 1.0,
    max_duration: float = math.inf,
) -> PlannedMotion:
    """Sample blocks every ``sample_period`` (s), ``settle`` (s) more.

    Parameters
    ----------
    blocks
        Motions and pauses in order; each motion starts where the one before ended.
    start
        Position (X, Y, Z) in m before the first block.
    limits
        Each axis' limits by name (the machine's axes, in order).
    sample_period
        Interpolation period, s.
    settle
        Standstill kept after the last block, s.
    path_control
        The path control mode of the blocks whose program set none (exact stop by default).
    look_ahead
        Blocks the planner looks ahead.
    feed_override
        Factor on every programmed feed (1: 100 %); rapid traverses keep the axes' speed.
    max_duration
        Longest path time allowed, s: a path that must take longer is refused before it is
        planned in full.

    Raises
    ------
    InterpolationError
        When no profile within the limits is found, or the path takes longer than
        ``max_duration``.
    """
    runs = _runs(blocks)
    parts: list[Segments] = []
    dwell = 0.0
    for run in runs:
        if isinstance(run, Pause):
            dwell += run.duration
            continue
        feeds = [None if m.feed is None else m.feed * feed_override for m in run]
        parts.append(Segments.of([m.element for m in run], feeds))
    fastest = dwell + sum(float(np.sum(p.lengths / p.path_limits(limits)[:, 0])) for p in parts)
    if fastest > max_duration:
        raise InterpolationError(
            f"the path takes at least {fastest:.4g} s, longer than the {max_duration:.4g} s a "
            "run may last (run.max_samples)"
        )
    pieces: list[tuple[float, Profile | None, float]] = []  # start time, profile, path length
    planned: list[Segments] = []
    feeds_out: list[BlockFeed] = []
    t, along, offset = 0.0, 0.0, 0
    motions: list[Motion] = []
    for run in runs:
        if isinstance(run, Pause):
            pieces.append((t, Profile(*_STILL[:5], run.duration), along))
            t += run.duration
            continue
        part = parts[len(planned)]
        controls = [m.path_control or path_control for m in run]
        merged, last_block = merge_straight(part, *_mergeable(part, controls))
        segments, joins = blend(
            merged,
            np.array([controls[k].blends for k in last_block]),
            _blend_tolerances(controls, last_block),
        )
        spans, top_merged = _plan_run(segments, joins, limits, sample_period, look_ahead)
        top = np.repeat(top_merged[merged.block], np.diff(last_block, prepend=-1))
        starts = np.concatenate(([0.0], np.cumsum(segments.lengths)))
        for span in spans:
            pieces.append((t, span.profile, along + float(starts[span.first])))
            t += span.profile.duration
        along += float(starts[-1])
        planned.append(dataclasses.replace(segments, block=segments.block + offset))
        caps = dataclasses.replace(part, feed=np.full(len(part), np.nan)).path_limits(limits)
        for k, motion in enumerate(run):
            programmed = None if math.isnan(part.feed[k]) else float(part.feed[k])
            stop_after = "G61" if not controls[k].blends else "end" if k == len(run) - 1 else None
            capped = programmed is not None and caps[k, 0] < programmed * (1 - FEED_SHORTFALL)
            feeds_out.append(
                BlockFeed(
                    motion.line,
                    programmed,
                    float(top[k]),
                    float(caps[k, 0]),
                    cap_reason(motion.element, limits) if capped else "",
                    stop_after,
                )
            )
        offset += len(run)
        motions.extend(run)
    end_time = t
    times = np.arange(int(math.floor((end_time + settle) / sample_period + 1e-9)) + 1)
    times = times * sample_period
    points = np.tile(np.asarray(start, dtype=np.float64), (len(times), 1))
    if planned:
        path = concatenate(planned)
        lengths = path.lengths
        starts = np.concatenate(([0.0], np.cumsum(lengths)[:-1]))
        t0 = np.array([p[0] for p in pieces])
        owner = np.clip(np.searchsorted(t0, times, side="right") - 1, 0, len(pieces) - 1)
        s = _evaluate([p[1] for p in pieces], owner, times - t0[owner])[0]
        total = float(starts[-1] + lengths[-1])
        along_path = np.clip(np.array([p[2] for p in pieces])[owner] + s, 0.0, total)
        along_path[times >= end_time] = total
        index = np.clip(np.searchsorted(starts, along_path, side="right") - 1, 0, len(path) - 1)
        local = np.clip(along_path - starts[index], 0.0, lengths[index])
        points = path.points(index, local)
    axes = tuple(limits)
    columns = [COORDINATE[name] for name in axes]
    return PlannedMotion(
        axes,
        sample_period,
        points[:, columns],
        tuple(m.element for m in motions),
        end_time,
        tuple(feeds_out),
    )


def plan_program(
    program: Program,
    limits: dict[str, AxisLimits],
    sample_period: float,
    settle: float,
    **planning: Any,
) -> PlannedMotion:
    """The per-axis references of a part program (:func:`plan_blocks` of its blocks from its
    start, ``planning`` the path control, look-ahead, feed override and longest duration it
    takes), its travel checked first (:func:`check_travel`)."""
    if not program.elements:
        raise InterpolationError(f"{program.source}: the program has no motion")
    check_travel(program.blocks, limits, program.source)
    try:
        return plan_blocks(program.blocks, program.start, limits, sample_period, settle, **planning)
    except InterpolationError as exc:
        raise InterpolationError(f"{program.source}: {exc}") from None


def check_travel(blocks, limits: dict[str, AxisLimits], source: str) -> None:
    """Refuse a path that leaves an axis' travel (its soft limits), naming the line, the axis
    and the limit; the path is checked as programmed (a blend stays inside its corner).

    Raises
    ------
    InterpolationError
        ``SOURCE: line N: the path reaches X = 250 mm, beyond axis X's travel [-200, 200] mm
        (axes.X.limits.travel)``.
    """
    motions = [b for b in blocks if isinstance(b, Motion)]
    bounded = {name: lim.travel for name, lim in limits.items() if lim.travel is not None}
    if not motions or not bounded:
        return
    low, high = (
        np.array(ends) for ends in zip(*(m.element.extent() for m in motions), strict=True)
    )
    for name, (least, most) in bounded.items():
        column = COORDINATE[name]
        outside = np.flatnonzero((low[:, column] < least) | (high[:, column] > most))
        if len(outside):
            k = int(outside[0])
            value = low[k, column] if low[k, column] < least else high[k, column]
            where = f"line {motions[k].line}: " if motions[k].line else ""
            raise InterpolationError(
                f"{source}: {where}the path reaches {name} = {value * 1e3:.6g} mm, beyond "
                f"axis {name}'s travel [{least * 1e3:g}, {most * 1e3:g}] mm "
                f"(axes.{name}.limits.travel)"
            )


def feed_warnings(motion: PlannedMotion) -> list[str]:
    """Where the feed reached falls short of the programmed one, for a reader.

    A block whose element does not allow its feed (an axis' velocity limit, the centripetal
    acceleration on an arc) is *capped*; a stretch of blocks of one feed between stops whose top
    speed stays below the feed is *too short* to reach it. Consecutive blocks of one kind and
    feed are said together.
    """
    found: list[tuple[BlockFeed, str]] = []
    stretch: list[BlockFeed] = []

    def close() -> None:
        if stretch and max(f.reached for f in stretch) < stretch[0].programmed * (
            1 - FEED_SHORTFALL
        ):
            why = "too short to reach it at the axes' acceleration and jerk"
            if stretch[-1].stop_after == "G61":
                why += " (an exact stop at every block end, G61; G64 P<tolerance> blends)"
            found.extend((f, why) for f in stretch)
        stretch.clear()

    for feed in motion.feeds:
        if feed.programmed is None:
            close()
            continue
        if stretch and feed.programmed != stretch[0].programmed:
            close()
        if feed.cap < feed.programmed * (1 - FEED_SHORTFALL):
            close()
            why = f"capped at {feed.cap * 60e3:.0f} mm/min by {feed.cap_reason}"
            if feed.reached < feed.cap * (1 - FEED_SHORTFALL):
                why += ", and too short to reach even that"
            found.append((feed, why))
            continue
        stretch.append(feed)
        if feed.stop_after is not None:
            close()
    close()
    warnings = []
    k = 0
    while k < len(found):
        first, why = found[k]
        last = k
        while (
            last + 1 < len(found)
            and found[last + 1][1] == why
            and found[last + 1][0].programmed == first.programmed
        ):
            last += 1
        group = [f for f, _ in found[k : last + 1]]
        reached = [f.reached * 60e3 for f in group]
        span = f"{min(reached):.0f}" + (
            f"-{max(reached):.0f}" if max(reached) - min(reached) >= 0.5 else ""
        )
        lines = (
            f"line {first.line}"
            if len(group) == 1
            else f"lines {first.line}-{group[-1].line} ({len(group)} blocks)"
        )
        warnings.append(
            f"{lines}: feed {span} mm/min reached of {first.programmed * 60e3:.0f} mm/min "
            f"programmed: {why}"
        )
        k = last + 1
    return warnings
