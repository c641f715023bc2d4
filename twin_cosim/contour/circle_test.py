"""The circular test (ISO 230-4) on a machine: a circle at constant feed, run and evaluated.

The machine interpolates one arc around the centre (the origin of the axes, X-Y plane): a
feed-in of whole quarter turns in which the feed ramps up (jerk-limited, within the axes'
limits), the data circle of 360 degrees at constant feed starting at 45 degrees (in the middle
of a quadrant, so that every quadrant transition, 0, 90, 180 and 270 degrees, lies inside it),
and a feed-out as long as the feed-in. The data circle is evaluated by
:mod:`twin_cosim.contour.iso230`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from twin_cosim.contour.gcode import Motion
from twin_cosim.contour.interpolation import PlannedMotion, plan_block, plan_blocks
from twin_cosim.contour.iso230 import CircleResult, evaluate_circle
from twin_cosim.contour.machine_run import MachinePlants, MachineRecord, run_machine
from twin_cosim.contour.path import Arc
from twin_cosim.scenario.machine import MachineScenario

DIRECTIONS = ("cw", "ccw")
DATA_START_DEG = 45.0
MM_PER_MIN = 1e-3 / 60.0  # m/s per mm/min


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
    """The test's motion on the machine: feed-in, data circle and feed-out as one arc."""
    limits = {axis.name: axis.limits for axis in machine.axes}
    quarter = spec.radius * math.pi / 2
    trial = Arc((0.0, 0.0), spec.radius, 0.0, spec.sign * 4 * math.pi)
    ramp = float(plan_block(trial, spec.feed, limits).p[3])  # path length of the feed ramp, m
    feed_in = math.pi / 2 * max(1, math.ceil(ramp / quarter * (1 + 1e-9)))
    start = math.radians(DATA_START_DEG) - spec.sign * feed_in
    arc = Arc((0.0, 0.0), spec.radius, start, spec.sign * (2 * math.pi + 2 * feed_in))
    begin = arc.points(np.array([0.0]))[0]
    motion = plan_blocks(
        [Motion(arc, spec.feed, 0)], tuple(begin), limits, machine.sample_period, machine.settle
    )
    return motion, arc


def data_circle(contour: pd.DataFrame, arc: Arc) -> np.ndarray:
    """Rows of the contour record whose reference lies on the data circle (360 degrees)."""
    angle = np.unwrap(np.arctan2(contour["y_ref"].to_numpy(), contour["x_ref"].to_numpy()))
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
    speed = motion.speeds[0]
    result = evaluate_circle(record.contour[data], spec.radius, spec.direction, speed)
    return CircleRun(spec, motion, record, data, result)
