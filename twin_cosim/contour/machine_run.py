"""A run of a machine: the planned motion on every axis together, its contour and its figure.

The per-axis references of a :class:`~twin_cosim.contour.interpolation.PlannedMotion` are
interpolated onto the position-loop grid (:func:`twin_cosim.reference.interpolate`), every axis
runs on its own plant instance in the master (:func:`twin_cosim.cosim.run_axes`), and the
contour record puts the programmed and the actual positions side by side with the contour
error: the distance of the tool point to the programmed path (the tool point is the axes'
positions moved by the machine's geometric errors,
:class:`~twin_cosim.scenario.machine.MachineGeometry`). :func:`plot_contour` draws a
program's run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twin_cosim.contour.gcode import Program
from twin_cosim.contour.interpolation import PlannedMotion, plan_program
from twin_cosim.contour.path import distance_to_path
from twin_cosim.cosim import AxisRun, run_axes
from twin_cosim.metrics import UM_PER_M, compute_metrics
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid, interpolate
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario.machine import MachineGeometry, MachineScenario

MAGNIFICATION_SHARE = 0.05  # the drawn contour error at its largest: this share of the part's size


class MachinePlants:
    """One plant FMU instance per axis of a machine: loaded once, reset per run.

    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, machine: MachineScenario) -> None:
        self.plants: dict[str, Plant] = {}
        try:
            for axis in machine.axes:
                self.plants[axis.name] = Plant(axis.plant_fmu(), instance_name=axis.name)
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Free every instance."""
        for plant in self.plants.values():
            plant.close()
        self.plants = {}

    def __enter__(self) -> MachinePlants:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


@dataclass(frozen=True)
class MachineRecord:
    """What a machine run recorded.

    Attributes
    ----------
    axes : dict
        Axis name -> its record (columns of :data:`twin_cosim.cosim.RECORD_COLUMNS`).
    contour : RunRecord
        One row per position-loop sample: ``t`` (s), ``<axis>_ref`` and ``<axis>`` (m) of each
        axis (lower-case names), on a machine with geometric errors ``x_tool`` and ``y_tool``
        (m, the tool point), ``contour_error`` (m, distance of the tool point to the
        programmed path).
    """

    axes: dict[str, RunRecord]
    contour: RunRecord


def axis_grids(machine: MachineScenario, motion: PlannedMotion) -> dict[str, ReferenceGrid]:
    """Each axis' reference on the position-loop grid.

    Raises
    ------
    ValueError
        When the run would hold more position-loop samples than ``run.max_samples``.
    """
    period = machine.axes[0].settings.position_period
    samples = (len(motion.samples) - 1) * motion.sample_period / period + 1
    if samples > machine.max_samples:
        raise ValueError(
            f"{machine.source}: the path takes {motion.end_time:g} s, {samples:.4g} position-loop "
            f"samples, more than run.max_samples = {machine.max_samples}"
        )
    return {
        name: interpolate(motion.samples[:, k], motion.sample_period, period)
        for k, name in enumerate(motion.axes)
    }


def contour_record(
    records: dict[str, RunRecord], motion: PlannedMotion, geometry: MachineGeometry
) -> RunRecord:
    """The contour record of per-axis records (see :class:`MachineRecord`)."""
    first = next(iter(records.values()))
    columns = {"t": first["t"]}
    actual = np.zeros((len(first), 3))
    for name, record in records.items():
        columns[f"{name.lower()}_ref"] = record["x_ref"]
        columns[name.lower()] = record["x"]
        actual[:, "XYZ".index(name)] = record["x"]
    if not geometry.is_ideal:
        actual[:, 0], actual[:, 1] = geometry.tool_point(actual[:, 0], actual[:, 1])
        columns["x_tool"], columns["y_tool"] = actual[:, 0].copy(), actual[:, 1].copy()
    columns["contour_error"] = distance_to_path(motion.elements, actual)
    units = {name: "s" if name == "t" else "m" for name in columns}
    return RunRecord.from_columns(columns, units)


def run_machine(
    machine: MachineScenario,
    motion: PlannedMotion,
    plants: MachinePlants,
    fast: bool = True,
    abort_error: float = math.inf,
) -> MachineRecord:
    """Run a planned motion on every axis together.

    Parameters
    ----------
    machine
        The axes' plants, controllers and rates.
    motion
        Per-axis references every interpolation period (the machine's axes, in order).
    plants
        The axes' plant instances (reset here).
    fast
        The compiled path (default) or the fmpy reference path.
    abort_error
        Stop with :class:`~twin_cosim.cosim.RunAborted` once an axis' |x_ref - x| exceeds
        this (m).
    """
    if motion.axes != machine.axis_names:
        raise ValueError(f"motion of axes {motion.axes} on a machine of {machine.axis_names}")
    grids = axis_grids(machine, motion)
    runs = [
        AxisRun(
            axis.name,
            plants.plants[axis.name],
            grids[axis.name],
            axis.tuned,
            axis.settings,
            {**axis.plant_parameters, "load_position_start": float(grids[axis.name].position[0])},
        )
        for axis in machine.axes
    ]
    recorded = run_axes(runs, fast, abort_error)
    records = {name: axis.position_loop for name, axis in recorded.items()}
    return MachineRecord(records, contour_record(records, motion, machine.geometry))


def tool_path(contour: RunRecord) -> tuple[np.ndarray, np.ndarray]:
    """The tool point's X and Y (m) of a contour record: the axes' positions on a machine
    without geometric errors."""
    if "x_tool" in contour:
        return contour["x_tool"], contour["y_tool"]
    return contour["x"], contour["y"]


def longest_path(machine: MachineScenario) -> float:
    """The longest path time (s) a run of the machine may have: ``run.max_samples`` position-loop
    samples, the settle time included."""
    period = machine.axes[0].settings.position_period
    return (machine.max_samples - 1) * period - machine.settle


def contour_metrics(record: MachineRecord) -> dict[str, float]:
    """Contour error over the run: ``contour_error_max_um`` and ``contour_error_rms_um`` (um)."""
    error = record.contour["contour_error"] * UM_PER_M
    return {
        "contour_error_max_um": float(np.max(error)),
        "contour_error_rms_um": float(np.sqrt(np.mean(error**2))),
    }


def axis_metrics(record: MachineRecord) -> dict[str, dict[str, float]]:
    """The single-axis metrics of each axis (E_pk um, ITAE um.s^2, IAU A.s, ...) by name."""
    return {name: compute_metrics(axis).as_dict() for name, axis in record.axes.items()}


def plan_on(machine: MachineScenario, program: Program, feed_override: float = 1.0):
    """The planned motion of a part program on the machine (its limits, interpolation period,
    path control, look-ahead and longest run), the feed override a factor (1: 100 %)."""
    return plan_program(
        program,
        machine.limits,
        machine.sample_period,
        machine.settle,
        path_control=machine.path_control,
        look_ahead=machine.look_ahead,
        feed_override=feed_override,
        max_duration=longest_path(machine),
    )


def plot_contour(record: MachineRecord, title: str, command: str, path: Path) -> Path:
    """Programmed and actual path (the deviation magnified), contour error and axis errors.

    Parameters
    ----------
    record
        The machine run.
    title
        Figure title.
    command
        The command that made the figure (written under the title).
    path
        PNG file to write; returned.
    """
    import matplotlib  # only to draw

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    contour = record.contour
    t = contour["t"]
    ref = contour.select(["x_ref", "y_ref"]).to_numpy()
    actual = np.column_stack(tool_path(contour))
    error = contour["contour_error"]
    size = float(np.ptp(ref, axis=0).max()) or 1e-3
    gain = MAGNIFICATION_SHARE * size / max(float(error.max()), 1e-12)
    fig = plt.figure(figsize=(11, 8.5))
    grid = fig.add_gridspec(2, 2, width_ratios=(1, 1.3))
    ax = fig.add_subplot(grid[:, 0])
    ax.plot(ref[:, 0] * 1e3, ref[:, 1] * 1e3, color="k", lw=1, label="programmed")
    drawn = ref + gain * (actual - ref)
    ax.plot(
        drawn[:, 0] * 1e3,
        drawn[:, 1] * 1e3,
        color="tab:red",
        lw=1,
        label=f"actual, deviation x{gain:.3g}",
    )
    ax.set_aspect("equal")
    ax.set_xlabel("X [mm]")
    ax.set_ylabel("Y [mm]")
    ax.legend(loc="best", fontsize=8)
    top = fig.add_subplot(grid[0, 1])
    top.plot(t, error * UM_PER_M, lw=0.8, color="tab:red")
    top.set_ylabel("contour error [um]")
    top.set_title(
        f"contour error max {error.max() * UM_PER_M:.2f} um, "
        f"RMS {np.sqrt(np.mean(error**2)) * UM_PER_M:.2f} um",
        fontsize=9,
    )
    bottom = fig.add_subplot(grid[1, 1], sharex=top)
    for name, axis in record.axes.items():
        bottom.plot(axis["t"], axis["error"] * UM_PER_M, lw=0.8, label=f"{name}: x_ref - x")
    bottom.set_ylabel("axis position error [um]")
    bottom.set_xlabel("t [s]")
    bottom.legend(fontsize=8)
    fig.suptitle(f"{title}\n{command}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
