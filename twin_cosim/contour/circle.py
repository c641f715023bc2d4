"""The circular test (ISO 230-4) on a machine: a circle at constant feed, run, evaluated, drawn.

The machine interpolates one arc around the centre (the origin of the axes, X-Y plane): a
feed-in of whole quarter turns in which the feed ramps up (jerk-limited, within the axes'
limits), the data circle of 360 degrees at constant feed starting at 45 degrees (in the middle
of a quadrant, so that every quadrant transition, 0, 90, 180 and 270 degrees, lies inside it),
and a feed-out as long as the feed-in.

On the data circle (360 degrees of actual positions around the nominal centre, the origin):

- circular deviation ``G``: the radial width of the band between two concentric circles that
  envelop the path, centred on its least-squares circle;
- radial deviation ``F``: the path against the nominal circle (nominal centre and radius):
  ``F_max`` outward, ``F_min`` inward; ``F`` the larger in magnitude;
- circular hysteresis ``H`` (CW against CCW, :func:`hysteresis`): the largest radial difference
  of the two paths at one angle;
- reversal spikes: at each quadrant transition (0, 90, 180, 270 degrees: the axis whose speed
  passes through zero reverses, X at 0 and 180, Y at 90 and 270), the largest departure of the
  radial deviation from its smooth part (orders 0 to 2 of the angle, fitted outside the
  transitions) within 40 degrees after the transition; its height (um, + outward) and width
  (ms, where the departure stays above half the height);
- servo mismatch: the order-2 part of the radial deviation about the least-squares centre, an
  ellipse with axes at 45/135 degrees when the axes' following errors differ. With lag times
  T_X, T_Y (1/K_v for a P position loop without velocity feedforward) the radius is about
  R (1 - v (T_Y - T_X) / (2 R) sin 2 theta): counter-clockwise, the major axis lies at 135
  degrees when Y lags (at 45 when X lags), clockwise the other way round; its size (peak to
  peak) is about v |T_X - T_Y|.

The circle is evaluated on the tool's path: the axes' positions moved by the machine's geometric
errors (:class:`~twin_cosim.scenario.machine.MachineGeometry`), as a ballbar sees it.
:mod:`~twin_cosim.contour.ballbar` fits the ballbar's diagnostics to it,
:mod:`~twin_cosim.contour.circle_report` runs the test as ``twin circle`` does and draws it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from twin_cosim.contour.gcode import Motion
from twin_cosim.contour.interpolation import (
    InterpolationError,
    PlannedMotion,
    check_travel,
    first_limits,
    plan_block,
    plan_blocks,
)
from twin_cosim.contour.machine_run import (
    MachinePlants,
    MachineRecord,
    longest_path,
    run_machine,
    tool_path,
)
from twin_cosim.contour.path import Arc
from twin_cosim.metrics import UM_PER_M
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario.machine import MachineScenario

DIRECTIONS = ("cw", "ccw")
DATA_START_DEG = 45.0
MM_PER_MIN = 1e-3 / 60.0  # m/s per mm/min
TRANSITIONS_DEG = (0.0, 90.0, 180.0, 270.0)
REVERSING_AXIS = {0.0: "X", 90.0: "Y", 180.0: "X", 270.0: "Y"}
SPIKE_WINDOW_DEG = 40.0  # after a transition, where its spike is looked for
SPIKE_LEAD_DEG = 2.0  # before it (the actual path may reverse a little early)
SMOOTH_ORDERS = 2  # the smooth part of the radial deviation: orders 0..2 of the angle
HYSTERESIS_STEP_DEG = 0.5
MISMATCH_SHARE = 0.2  # an ellipse this share of G or more names the lagging axis


@dataclass(frozen=True)
class CircleSpec:
    """One circle of the test.

    Attributes
    ----------
    radius : float
        Nominal radius, m.
    feed : float
        Programmed feed, m/s.
    direction : str
        ``cw`` (G02) or ``ccw`` (G03), seen from +Z.
    """

    radius: float
    feed: float
    direction: str

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"circle radius must be > 0 m, got {self.radius}")
        if not (math.isfinite(self.feed) and self.feed > 0):
            raise ValueError(f"circle feed must be > 0 m/s, got {self.feed}")
        if self.direction not in DIRECTIONS:
            raise ValueError(f"circle direction must be one of {DIRECTIONS}, got {self.direction}")

    @property
    def sign(self) -> float:
        """+1 counter-clockwise, -1 clockwise."""
        return 1.0 if self.direction == "ccw" else -1.0


@dataclass(frozen=True)
class Spike:
    """The reversal spike at one quadrant transition.

    Attributes
    ----------
    angle_deg : float
        The transition's angle, degrees (0, 90, 180, 270).
    axis : str
        The axis that reverses there.
    height_um : float
        Peak departure of the radial deviation from its smooth part, um (+ outward).
    width_ms : float
        Time the departure stays above half the height around the peak, ms.
    peak_deg : float
        Angle of the peak, degrees.
    """

    angle_deg: float
    axis: str
    height_um: float
    width_ms: float
    peak_deg: float


@dataclass(frozen=True)
class CircleResult:
    """The ISO 230-4 figures and signatures of one direction.

    Attributes
    ----------
    direction : str
        ``cw`` or ``ccw``.
    G_um, F_um, F_max_um, F_min_um : float
        Circular deviation, radial deviation (largest magnitude, outward, inward), um.
    centre_um : tuple
        Least-squares centre against the nominal one, um (X, Y).
    radius_um : float
        Least-squares radius minus the nominal radius, um.
    speed_mm_min : float
        Path speed on the data circle, mm/min.
    spikes : list of Spike
        One per quadrant transition.
    mismatch : dict
        The order-2 ellipse: ``size_um`` (peak to peak), ``major_axis_deg`` (0-180),
        ``lagging_axis`` (the axis whose following error is the larger, when the ellipse lies
        within 15 degrees of 45/135).
    angle_deg, deviation_um : numpy.ndarray
        The data circle: angle about the nominal centre (degrees) and radial deviation from the
        nominal circle (um) of each sample, for plots and the hysteresis.
    """

    direction: str
    G_um: float
    F_um: float
    F_max_um: float
    F_min_um: float
    centre_um: tuple[float, float]
    radius_um: float
    speed_mm_min: float
    spikes: list[Spike]
    mismatch: dict[str, Any]
    angle_deg: np.ndarray = field(repr=False)
    deviation_um: np.ndarray = field(repr=False)

    def summary(self) -> dict[str, Any]:
        """JSON-ready figures (without the per-sample arrays)."""
        return {
            "direction": self.direction,
            "G_um": self.G_um,
            "F_um": self.F_um,
            "F_max_um": self.F_max_um,
            "F_min_um": self.F_min_um,
            "centre_um": list(self.centre_um),
            "radius_um": self.radius_um,
            "speed_mm_min": self.speed_mm_min,
            "spikes": [asdict(s) for s in self.spikes],
            "mismatch": self.mismatch,
        }


def least_squares_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Centre (m, m) and radius (m) of the circle nearest the points in least squares.

    The algebraic (Kasa) fit, refined by Gauss-Newton steps on the geometric distances.
    """
    design = np.column_stack((x, y, np.ones_like(x)))
    a, b, c = np.linalg.lstsq(design, x**2 + y**2, rcond=None)[0]
    cx, cy = a / 2, b / 2
    r = math.sqrt(c + cx**2 + cy**2)
    for _ in range(5):
        dx, dy = x - cx, y - cy
        d = np.hypot(dx, dy)
        jacobian = np.column_stack((-dx / d, -dy / d, -np.ones_like(d)))
        step = np.linalg.lstsq(jacobian, -(d - r), rcond=None)[0]
        cx, cy, r = cx + step[0], cy + step[1], r + step[2]
    return float(cx), float(cy), float(r)


def _smooth_part(angle: np.ndarray, deviation: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The orders 0..SMOOTH_ORDERS of ``deviation`` over ``angle`` (rad), fitted on ``keep``."""
    columns = [np.ones_like(angle)]
    for k in range(1, SMOOTH_ORDERS + 1):
        columns += [np.cos(k * angle), np.sin(k * angle)]
    basis = np.column_stack(columns)
    coefficients = np.linalg.lstsq(basis[keep], deviation[keep], rcond=None)[0]
    return basis @ coefficients


def travelled_since(angle_deg: np.ndarray, transition: float, sign: float) -> np.ndarray:
    """Angle travelled since ``transition`` (degrees, in the direction of motion ``sign``, +1
    counter-clockwise), in [-180, 180)."""
    return (sign * (angle_deg - transition) + 180.0) % 360.0 - 180.0


def _spike(
    t: np.ndarray, angle_deg: np.ndarray, residual: np.ndarray, transition: float, sign: float
) -> Spike:
    """The spike of one transition from the residual radial deviation (um)."""
    travelled = travelled_since(angle_deg, transition, sign)
    window = np.flatnonzero((travelled >= -SPIKE_LEAD_DEG) & (travelled <= SPIKE_WINDOW_DEG))
    if len(window) == 0:
        return Spike(transition, REVERSING_AXIS[transition], 0.0, 0.0, transition)
    window = window[np.argsort(t[window])]
    peak = window[np.argmax(np.abs(residual[window]))]
    height = float(residual[peak])
    above = np.abs(residual[window]) >= abs(height) / 2
    above &= np.sign(residual[window]) == np.sign(height)
    at = int(np.flatnonzero(window == peak)[0])
    first, last = at, at
    while first > 0 and above[first - 1]:
        first -= 1
    while last < len(window) - 1 and above[last + 1]:
        last += 1
    dt = float(np.median(np.diff(t[window]))) if len(window) > 1 else 0.0
    return Spike(
        angle_deg=transition,
        axis=REVERSING_AXIS[transition],
        height_um=height,
        width_ms=(last - first + 1) * dt * 1e3,
        peak_deg=float(angle_deg[peak]),
    )


def _mismatch(angle: np.ndarray, deviation: np.ndarray, sign: float) -> dict[str, Any]:
    """The order-2 ellipse of the radial deviation (um) about the least-squares centre.

    The lagging axis is named when the ellipse lies within 15 degrees of 45 or 135 degrees and
    is at least :data:`MISMATCH_SHARE` of the deviation's range (and 0.1 um).
    """
    basis = np.column_stack((np.ones_like(angle), np.cos(2 * angle), np.sin(2 * angle)))
    _, c, s = np.linalg.lstsq(basis, deviation, rcond=None)[0]
    size = float(2 * math.hypot(c, s))
    major = math.degrees(math.atan2(s, c)) / 2 % 180.0
    lagging = None
    if size >= max(0.1, MISMATCH_SHARE * float(np.ptp(deviation))):
        if abs(major - 135.0) <= 15.0:
            lagging = "Y" if sign > 0 else "X"
        elif abs(major - 45.0) <= 15.0:
            lagging = "X" if sign > 0 else "Y"
    return {"size_um": size, "major_axis_deg": major, "lagging_axis": lagging}


def evaluate_circle(data: RunRecord, radius: float, direction: str, speed: float) -> CircleResult:
    """ISO 230-4 figures and signatures of one direction's data circle.

    Parameters
    ----------
    data
        Rows of the contour record on the data circle: ``t`` (s), ``x``, ``y`` (m).
    radius
        Nominal radius, m (nominal centre: the origin).
    direction
        ``cw`` or ``ccw``.
    speed
        Path speed on the data circle, m/s.
    """
    if len(data) < 16:
        raise ValueError(f"a data circle of {len(data)} samples is too short to evaluate")
    t = data["t"]
    x, y = data["x"], data["y"]
    sign = 1.0 if direction == "ccw" else -1.0
    cx, cy, r_fit = least_squares_circle(x, y)
    about_fit = np.hypot(x - cx, y - cy) - r_fit
    nominal = (np.hypot(x, y) - radius) * UM_PER_M
    angle = np.arctan2(y, x)
    angle_deg = np.degrees(angle) % 360.0
    near = np.zeros(len(t), dtype=bool)
    for transition in TRANSITIONS_DEG:
        travelled = travelled_since(angle_deg, transition, sign)
        near |= (travelled >= -SPIKE_LEAD_DEG) & (travelled <= SPIKE_WINDOW_DEG)
    deviation = about_fit * UM_PER_M
    keep = ~near if np.count_nonzero(~near) > 2 * SMOOTH_ORDERS + 1 else np.ones_like(near)
    residual = deviation - _smooth_part(angle, deviation, keep)
    spikes = [_spike(t, angle_deg, residual, tr, sign) for tr in TRANSITIONS_DEG]
    fit_angle = np.arctan2(y - cy, x - cx)
    return CircleResult(
        direction=direction,
        G_um=float(np.ptp(deviation)),
        F_um=float(np.max(np.abs(nominal))),
        F_max_um=float(np.max(nominal)),
        F_min_um=float(np.min(nominal)),
        centre_um=(cx * UM_PER_M, cy * UM_PER_M),
        radius_um=(r_fit - radius) * UM_PER_M,
        speed_mm_min=speed * 60e3,
        spikes=spikes,
        mismatch=_mismatch(fit_angle, deviation, sign),
        angle_deg=angle_deg,
        deviation_um=nominal,
    )


def on_grid(result: CircleResult, grid: np.ndarray) -> np.ndarray:
    """The radial deviation (um) of an evaluated path at the angles ``grid`` (degrees)."""
    order = np.argsort(result.angle_deg)
    return np.interp(grid, result.angle_deg[order], result.deviation_um[order], period=360.0)


def hysteresis(first: CircleResult, second: CircleResult) -> float:
    """Circular hysteresis H (um): the largest radial difference of two directions' paths at
    one angle (each interpolated on a grid of :data:`HYSTERESIS_STEP_DEG`)."""
    grid = np.arange(0.0, 360.0, HYSTERESIS_STEP_DEG)
    return float(np.max(np.abs(on_grid(first, grid) - on_grid(second, grid))))


@dataclass(frozen=True)
class CircleRun:
    """A circle run on the machine: its motion, record and ISO 230-4 evaluation.

    Attributes
    ----------
    spec : CircleSpec
        The circle asked for.
    motion : PlannedMotion
        The per-axis references.
    record : MachineRecord
        The per-axis and contour records.
    data : numpy.ndarray
        Boolean mask of the contour record's rows on the data circle.
    result : CircleResult
        The evaluation.
    """

    spec: CircleSpec
    motion: PlannedMotion
    record: MachineRecord
    data: np.ndarray
    result: CircleResult


def circle_motion(machine: MachineScenario, spec: CircleSpec) -> tuple[PlannedMotion, Arc]:
    """The test's motion on the machine: feed-in, data circle and feed-out as one arc.

    Raises
    ------
    InterpolationError
        Before anything is planned, when the circle leaves an axis' travel or would take longer
        than a run may last (``run.max_samples``).
    """
    limits = machine.limits
    quarter = spec.radius * math.pi / 2
    trial = Arc((0.0, 0.0), spec.radius, 0.0, spec.sign * 4 * math.pi)
    name = f"circle of radius {spec.radius * 1e3:g} mm"
    check_travel([Motion(trial, spec.feed, 0)], limits, name)
    shortest = 3 * math.pi * spec.radius / first_limits(trial, spec.feed, limits)[0]
    if shortest > longest_path(machine):  # a turn and two quarters at least
        raise InterpolationError(
            f"{name} at {spec.feed / MM_PER_MIN:g} mm/min: takes at least {shortest:.4g} s, "
            f"longer than the {longest_path(machine):.4g} s a run may last (run.max_samples)"
        )
    ramp = float(plan_block(trial, spec.feed, limits).p[3])  # path length of the feed ramp, m
    feed_in = math.pi / 2 * max(1, math.ceil(ramp / quarter * (1 + 1e-9)))
    start = math.radians(DATA_START_DEG) - spec.sign * feed_in
    arc = Arc((0.0, 0.0), spec.radius, start, spec.sign * (2 * math.pi + 2 * feed_in))
    begin = arc.points(np.array([0.0]))[0]
    motion = plan_blocks(
        [Motion(arc, spec.feed, 0)], tuple(begin), limits, machine.sample_period, machine.settle
    )
    return motion, arc


def data_circle(contour: RunRecord, arc: Arc) -> np.ndarray:
    """Rows of the contour record whose reference lies on the data circle (360 degrees)."""
    angle = np.unwrap(np.arctan2(contour["y_ref"], contour["x_ref"]))
    travelled = math.copysign(1.0, arc.sweep) * (angle - arc.start_angle)
    feed_in = (abs(arc.sweep) - 2 * math.pi) / 2
    return (travelled >= feed_in) & (travelled < feed_in + 2 * math.pi)


def run_circle(
    machine: MachineScenario,
    plants: MachinePlants,
    spec: CircleSpec,
    fast: bool = True,
    abort_error: float = math.inf,
) -> CircleRun:
    """Run one circle of the test on the machine (a Z axis stands still) and evaluate it.

    ``abort_error`` (m): stop once an axis' |x_ref - x| exceeds it
    (:class:`~twin_cosim.cosim.RunAborted`).
    """
    motion, arc = circle_motion(machine, spec)
    record: MachineRecord = run_machine(machine, motion, plants, fast, abort_error)
    data = data_circle(record.contour, arc)
    x, y = tool_path(record.contour)
    tool = RunRecord.from_columns(
        {"t": record.contour["t"][data], "x": x[data], "y": y[data]}, {"t": "s", "x": "m", "y": "m"}
    )
    result = evaluate_circle(tool, spec.radius, spec.direction, motion.feeds[0].reached)
    return CircleRun(spec, motion, record, data, result)
