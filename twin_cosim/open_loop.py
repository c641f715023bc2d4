"""An open-loop run of the twin against its measurement: the speeds side by side, the velocity
gap, and the steady speed the twin predicts at each level of the commanded input.

An open-loop scenario (``reference.drive``, :mod:`twin_cosim.scenario.reference_section`) drives
the plant with a measured run's signal (e.g. an input torque stepped from one level to another)
instead of the cascade. Its figures:

- the **velocity gap**: the RMS of measured minus twin motor speed (rad/s) over the run, and the
  benchmark's relative error 100 ||w - w_sim|| / ||w|| (%); the position gap as the rotor angle
  (rad: the load position over the travel per radian);
- the **steady speeds**: each stretch where the commanded input holds one value (a *level*: of
  the run's input torque, whichever signal drives the plant,
  :attr:`~twin_cosim.measured.MeasuredRun.experiment_input`) ends at
  a steady speed; measured and twin speeds are averaged over the level's last
  :data:`STEADY_SHARE` and compared (relative error of the twin, %).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from twin_cosim.measured import MeasuredRun
from twin_cosim.run_record import RunRecord

STEADY_SHARE = 0.2  # the last share of a level over which its speed counts as steady
MIN_LEVEL_SAMPLES = 20  # a level shorter than this is a transition, not a level


@dataclass(frozen=True)
class Level:
    """One level of the commanded input and its steady speed.

    Attributes
    ----------
    start_s, end_s : float
        Where the commanded input holds the level, s.
    commanded : float
        The level, in the commanded input's unit (N.m or A).
    measured_rad_s, twin_rad_s : float
        Mean motor speed over the level's last :data:`STEADY_SHARE`, measured and the twin's,
        rad/s.
    """

    start_s: float
    end_s: float
    commanded: float
    measured_rad_s: float
    twin_rad_s: float

    @property
    def relative_error_pct(self) -> float:
        """The twin's steady speed against the measured one, %."""
        if self.measured_rad_s == 0.0:
            return float("nan")
        return 100.0 * (self.twin_rad_s - self.measured_rad_s) / self.measured_rad_s


@dataclass(frozen=True)
class OpenLoopComparison:
    """The twin's open-loop run against the measured run it replays.

    Attributes
    ----------
    run : str
        The measured run.
    drive, drive_unit : str
        The signal that drove the plant and its unit.
    commanded_unit : str
        The unit of the commanded input, whose levels are the run's.
    speed_rms_gap_rad_s : float
        RMS of measured minus twin motor speed, rad/s.
    speed_relative_error_pct : float
        100 ||w - w_sim|| / ||w||, %.
    angle_rms_gap_rad : float
        RMS of measured minus twin rotor angle, rad.
    levels : list of Level
        The commanded input's levels and their steady speeds, in time order.
    """

    run: str
    drive: str
    drive_unit: str
    commanded_unit: str
    speed_rms_gap_rad_s: float
    speed_relative_error_pct: float
    angle_rms_gap_rad: float
    levels: list[Level]

    def as_dict(self) -> dict:
        """The figures for JSON, each level with its relative error."""
        found = asdict(self)
        for level, row in zip(self.levels, found["levels"], strict=True):
            row["relative_error_pct"] = level.relative_error_pct
        return found


def levels(t: np.ndarray, commanded: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges where ``commanded`` holds one value, at least
    :data:`MIN_LEVEL_SAMPLES` long (``t`` in s, for the samples' order only)."""
    if len(t) != len(commanded) or len(t) == 0:
        raise ValueError("t and commanded must be non-empty arrays of one length")
    changes = np.flatnonzero(np.diff(commanded) != 0.0) + 1
    edges = np.concatenate(([0], changes, [len(commanded)]))
    return [
        (int(a), int(b))
        for a, b in zip(edges[:-1], edges[1:], strict=True)
        if b - a >= MIN_LEVEL_SAMPLES
    ]


def with_measured(record: RunRecord, run: MeasuredRun) -> RunRecord:
    """The twin's record with the measured position and motor speed beside its own
    (``measured_x`` [m], ``measured_motor_speed`` [rad/s]), at the record's times."""
    t = record["t"]
    return record.with_columns(
        {
            "measured_x": np.interp(t, run.t, run.x),
            "measured_motor_speed": np.interp(t, run.t, run.record["motor_speed"]),
        },
        {"measured_x": "m", "measured_motor_speed": "rad/s"},
    )


def compare_open_loop(
    run: MeasuredRun, record: RunRecord, travel_per_rad: float
) -> OpenLoopComparison:
    """The twin's open-loop ``record`` against the open-loop ``run`` it replays.

    Parameters
    ----------
    run
        The measured run as an open-loop run (:meth:`MeasuredRun.open_loop`: its drive, ``x``
        in m and ``motor_speed`` in rad/s).
    record
        The twin's run of it (columns ``t``, ``x``, ``motor_speed``).
    travel_per_rad
        The load position per rotor radian, m/rad (the angle gap is the position gap over it).
    """
    if run.drive is None:
        raise ValueError(f"{run.source}: not an open-loop run (no drive signal)")
    speed = run.record["motor_speed"]
    twin_speed = np.interp(run.t, record["t"], record["motor_speed"])
    twin_x = np.interp(run.t, record["t"], record["x"])
    commanded = run.experiment_input
    found = []
    for start, stop in levels(run.t, commanded):
        steady = slice(stop - max(int(STEADY_SHARE * (stop - start)), 1), stop)
        found.append(
            Level(
                float(run.t[start]),
                float(run.t[stop - 1]),
                float(commanded[start]),
                float(np.mean(speed[steady])),
                float(np.mean(twin_speed[steady])),
            )
        )
    gap = speed - twin_speed
    norm = float(np.linalg.norm(speed))
    return OpenLoopComparison(
        run.source,
        run.drive,
        run.record.units.get(run.drive, ""),
        run.record.units.get(run.experiment_signal, ""),
        float(np.sqrt(np.mean(gap**2))),
        100.0 * float(np.linalg.norm(gap)) / norm if norm else 0.0,
        float(np.sqrt(np.mean((run.x - twin_x) ** 2))) / travel_per_rad,
        found,
    )
