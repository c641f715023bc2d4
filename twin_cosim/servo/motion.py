"""The motions of a drive's commissioning tests, run on the master.

- **A step of the position setpoint at standstill** (:func:`step_grid`): the reference stands at
  the start position and the step is added to the position loop's setpoint through the
  master's position injection (:class:`~twin_cosim.cosim.Injections`), as a drive's step test
  adds it: no feedforward acts, the reference does not move.
- **Levels of constant speed** (:func:`speed_levels`): from standstill up to the first level at
  :data:`START_ACCELERATION`, then from level to level, each reached on a ramp of
  :data:`LEVEL_RAMP_S` and held for the dwell; a level's steady window is the part of its hold
  after :data:`SETTLE_SHARE` of it. A drive measuring friction comes to each speed from a
  higher one and gently: a fast approach through the low speeds where friction falls with
  speed (Stribeck) can start a stick-slip cycle that then lives on at speeds where a gentle
  approach stays steady (docs/servo.md).

Every motion is a reference on the position-loop grid, built exactly from pieces of constant
acceleration (no interpolating spline: the levels are exactly constant), and runs on the master
(:func:`run_motion`) with the controller's own functions, as every run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.cosim import AxisRecord, AxisRun, Injections, run_axes
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord

START_ACCELERATION = 0.5  # m/s^2 from standstill to the first level
LEVEL_RAMP_S = 0.1  # s from one level to the next
SETTLE_SHARE = 0.4  # of a level's hold, before its steady window


@dataclass(frozen=True)
class Level:
    """One level of constant speed of a run.

    Attributes
    ----------
    speed : float
        Carriage speed, m/s (signed).
    steady : slice
        Its steady window, position-loop samples.
    """

    speed: float
    steady: slice


def _piecewise(pieces: Sequence[tuple[int, float]], period: float, start: float) -> ReferenceGrid:
    """The reference of pieces (samples, acceleration m/s^2) from rest at ``start`` (m), exact
    at every position-loop sample (period s)."""
    samples = sum(n for n, _ in pieces) + 1
    x, v, a = np.empty(samples), np.empty(samples), np.zeros(samples)
    x[0], v[0] = start, 0.0
    k = 0
    for n, acceleration in pieces:
        tau = np.arange(1, n + 1) * period
        x[k + 1 : k + n + 1] = x[k] + v[k] * tau + 0.5 * acceleration * tau**2
        v[k + 1 : k + n + 1] = v[k] + acceleration * tau
        a[k : k + n] = acceleration
        k += n
    return ReferenceGrid(period, x, v, a)


def speed_levels(
    speeds: Sequence[float], dwell_s: float, period: float, start: float = 0.0
) -> tuple[ReferenceGrid, list[Level]]:
    """A run through ``speeds`` (m/s, signed, in the order given), each held ``dwell_s`` (s).

    Returns the reference on the position-loop grid (``period`` s, from ``start`` m) and each
    level with its steady window.
    """
    hold = max(2, round(dwell_s / period))
    pieces: list[tuple[int, float]] = []
    levels = []
    k, previous = 0, 0.0
    for speed in speeds:
        change = speed - previous
        ramp_s = abs(change) / START_ACCELERATION if not pieces else LEVEL_RAMP_S
        ramp = max(1, math.ceil(ramp_s / period))
        pieces += [(ramp, change / (ramp * period)), (hold, 0.0)]
        k += ramp + hold
        levels.append(Level(speed, slice(k - hold + round(SETTLE_SHARE * hold), k + 1)))
        previous = speed
    return _piecewise(pieces, period, start), levels


def step_grid(duration_s: float, period: float, start: float) -> ReferenceGrid:
    """The reference of a step test: standing at ``start`` (m) for ``duration_s`` (s)."""
    samples = round(duration_s / period) + 1
    still = np.zeros(samples)
    return ReferenceGrid(period, np.full(samples, start), still, still.copy())


def run_motion(
    plant: Plant,
    grid: ReferenceGrid,
    tuned: TunedParameters,
    settings: ControllerSettings,
    plant_parameters: Mapping[str, float],
    injections: Injections | None = None,
) -> AxisRecord:
    """One axis run of ``grid`` on the compiled master (no speed-loop record)."""
    axis = AxisRun("", plant, grid, tuned, settings, plant_parameters, injections or Injections())
    return run_axes([axis])[axis.name]


def level_statistics(
    record: RunRecord, levels: Sequence[Level], column: str
) -> tuple[np.ndarray, np.ndarray]:
    """The mean and standard deviation of a record's ``column`` over each level's steady
    window (the column's unit)."""
    values = np.asarray(record[column])
    means = np.array([values[level.steady].mean() for level in levels])
    spreads = np.array([values[level.steady].std() for level in levels])
    return means, spreads
