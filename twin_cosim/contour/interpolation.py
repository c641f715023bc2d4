"""The CNC's interpolator: path blocks to per-axis position references every 4 ms.

Each motion block is traversed from rest to rest (exact stop at block ends) along its path
length s with a jerk-limited profile s(t) (ruckig: time-optimal under limits on ds/dt, d2s/dt2,
d3s/dt3). The limits of a block follow from each axis' velocity, acceleration and jerk limits:

- a line with unit direction u: path limit = min over axes of (axis limit / |u_i|), so that
  every axis keeps within its own limit; G00 runs at that speed, G01 at min(F, it);
- an arc of radius R: a constant path speed v where the limits allow,
  v = min(F, v_axis, sqrt(rho a_axis R), (rho j_axis R^2)^(1/3)) with rho = 1/2 of the axes'
  acceleration and jerk kept for the centripetal terms (v^2/R, v^3/R^2), the rest for the
  tangential ramps.

Every planned block is checked on a fine time grid against each axis' limits (from the exact
derivatives of the element's geometry); a block that exceeds one is planned again slower. Dwells
hold the position. The samples are taken every ``sample_period`` (the interpolation period);
the position loop interpolates them (:func:`twin_cosim.reference.interpolate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from twin_cosim.contour.gcode import Motion, Pause, Program
from twin_cosim.contour.path import Element, Line
from twin_cosim.scenario.machine import AxisLimits

ARC_SHARE = 0.5  # share rho of the axes' acceleration and jerk kept for the centripetal terms
_COORDINATE = {"X": 0, "Y": 1, "Z": 2}
_CHECK_STEP = 2.5e-4  # s: time step of the limit check
_LIMIT_SLACK = 1e-6  # relative excess tolerated by the check (rounding)
_MAX_REPLANS = 40


class InterpolationError(ValueError):
    """A block cannot be planned within the axes' limits."""


@dataclass(frozen=True)
class Profile:
    """A rest-to-rest jerk-limited profile s(t) of one block (ruckig's seven phases).

    Attributes
    ----------
    starts : numpy.ndarray
        Start time of each phase, s (from the block's start).
    p, v, a, j : numpy.ndarray
        Path position (m), speed (m/s), acceleration (m/s^2) at each phase's start, and the
        phase's jerk (m/s^3).
    duration : float
        Length of the block, s.
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


def jerk_limited(length: float, speed: float, acceleration: float, jerk: float) -> Profile:
    """The time-optimal rest-to-rest profile over ``length`` (m) under the path limits
    ``speed`` (m/s), ``acceleration`` (m/s^2), ``jerk`` (m/s^3), from ruckig."""
    given = InputParameter(1)
    given.current_position = [0.0]
    given.target_position = [float(length)]
    given.max_velocity = [float(speed)]
    given.max_acceleration = [float(acceleration)]
    given.max_jerk = [float(jerk)]
    trajectory = Trajectory(1)
    result = Ruckig(1).calculate(given, trajectory)
    if result != Result.Working:
        raise InterpolationError(
            f"ruckig cannot plan {length:g} m at {speed:g} m/s, {acceleration:g} m/s^2, "
            f"{jerk:g} m/s^3: {result}"
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
    if isinstance(element, Line):
        length = element.length
        u = np.subtract(element.end, element.start) / length if length > 0 else np.zeros(3)
        return np.stack([np.outer(q, u) for q in (v, a, j)])
    sign = math.copysign(1.0, element.sweep)
    angle = element.angles(s)
    tangent = sign * np.column_stack((-np.sin(angle), np.cos(angle), np.zeros_like(angle)))
    inward = -np.column_stack((np.cos(angle), np.sin(angle), np.zeros_like(angle)))
    r = element.radius
    velocity = v[:, None] * tangent
    acceleration = a[:, None] * tangent + (v**2 / r)[:, None] * inward
    jerk = (j - v**3 / r**2)[:, None] * tangent + (3 * v * a / r)[:, None] * inward
    return np.stack([velocity, acceleration, jerk])


def _first_limits(
    element: Element, feed: float | None, limits: dict[str, AxisLimits]
) -> tuple[float, float, float]:
    """Path speed, acceleration and jerk limits of a block before the check (m/s, m/s^2, m/s^3)."""
    if isinstance(element, Line):
        u = np.abs(np.subtract(element.end, element.start)) / element.length
        bounds = []
        for quantity in ("velocity", "acceleration", "jerk"):
            bounds.append(
                min(
                    getattr(lim, quantity) / u[_COORDINATE[name]]
                    for name, lim in limits.items()
                    if u[_COORDINATE[name]] > 0
                )
            )
        speed = bounds[0] if feed is None else min(feed, bounds[0])
        return speed, bounds[1], bounds[2]
    plane = [limits[name] for name in ("X", "Y")]
    v_axis = min(lim.velocity for lim in plane)
    a_axis = min(lim.acceleration for lim in plane)
    j_axis = min(lim.jerk for lim in plane)
    r = element.radius
    speed = min(
        v_axis,
        math.sqrt(ARC_SHARE * a_axis * r),
        (ARC_SHARE * j_axis * r**2) ** (1 / 3),
    )
    if feed is not None:
        speed = min(speed, feed)
    return speed, (1 - ARC_SHARE) * a_axis, (1 - ARC_SHARE) * j_axis


def _worst_excess(element: Element, profile: Profile, limits: dict[str, AxisLimits]) -> float:
    """Largest ratio of an axis' |velocity|, |acceleration| or |jerk| to its limit."""
    tau = np.linspace(0.0, profile.duration, max(int(profile.duration / _CHECK_STEP), 2) + 1)
    tau = np.union1d(tau, np.clip(profile.starts, 0.0, profile.duration))
    derivatives = np.abs(axis_derivatives(element, profile, tau))
    worst = 0.0
    for name, lim in limits.items():
        column = _COORDINATE[name]
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
    speed, acceleration, jerk = _first_limits(element, feed, limits)
    for _ in range(_MAX_REPLANS):
        profile = jerk_limited(element.length, speed, acceleration, jerk)
        excess = _worst_excess(element, profile, limits)
        if excess <= 1 + _LIMIT_SLACK:
            return profile
        shrink = max(0.5, min(0.95, 1 / excess))
        speed, acceleration, jerk = speed * shrink, acceleration * shrink, jerk * shrink
    raise InterpolationError(f"line {line}: no profile within the axes' limits was found")


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
        The programmed path (lines and arcs, m).
    end_time : float
        When the path ends (the settle time follows), s.
    speeds : tuple of float
        Planned top path speed of each motion block, m/s.
    """

    axes: tuple[str, ...]
    sample_period: float
    samples: np.ndarray
    elements: tuple[Element, ...]
    end_time: float
    speeds: tuple[float, ...]


def plan_blocks(
    blocks: list[Motion | Pause] | tuple[Motion | Pause, ...],
    start: tuple[float, float, float],
    limits: dict[str, AxisLimits],
    sample_period: float,
    settle: float,
) -> PlannedMotion:
    """Sample blocks (exact stop at each end) every ``sample_period`` (s), ``settle`` (s) more.

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
    """
    pieces: list[tuple[float, float, Element | None, Profile | None, np.ndarray]] = []
    position = np.asarray(start, dtype=np.float64)
    t = 0.0
    speeds = []
    for block in blocks:
        if isinstance(block, Pause):
            pieces.append((t, block.duration, None, None, position))
            t += block.duration
            continue
        if block.element.length == 0.0:
            continue
        profile = plan_block(block.element, block.feed, limits, block.line)
        speeds.append(float(np.max(profile.v)) if len(profile.v) else 0.0)
        pieces.append((t, profile.duration, block.element, profile, position))
        t += profile.duration
        position = block.element.points(np.array([block.element.length]))[0]
    end_time = t
    times = np.arange(int(math.floor((end_time + settle) / sample_period + 1e-9)) + 1)
    times = times * sample_period
    points = np.tile(position, (len(times), 1))  # after the last block: its end
    for t0, duration, element, profile, at_start in reversed(pieces):
        inside = times >= t0 - 1e-12
        inside &= times < t0 + duration + 1e-12
        if element is None:
            points[inside] = at_start
        else:
            s = profile.evaluate(times[inside] - t0)[0]
            points[inside] = element.points(s)
    axes = tuple(limits)
    columns = [_COORDINATE[name] for name in axes]
    return PlannedMotion(
        axes,
        sample_period,
        points[:, columns],
        tuple(e for _, _, e, _, _ in pieces if e is not None),
        end_time,
        tuple(speeds),
    )


def plan_program(
    program: Program, limits: dict[str, AxisLimits], sample_period: float, settle: float
) -> PlannedMotion:
    """The per-axis references of a part program (see :func:`plan_blocks`)."""
    if not program.elements:
        raise InterpolationError(f"{program.source}: the program has no motion")
    return plan_blocks(program.blocks, program.start, limits, sample_period, settle)
