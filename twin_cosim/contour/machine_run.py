"""A run of a machine: the planned motion on every axis in lockstep, and its contour.

The per-axis references of a :class:`~twin_cosim.contour.interpolation.PlannedMotion` are
interpolated onto the position-loop grid (:func:`twin_cosim.reference.interpolate`), every axis
runs on its own plant instance (:mod:`twin_cosim.contour.lockstep`), and the contour record
puts the programmed and the actual positions side by side with the contour error: the distance
of the actual position to the programmed path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from twin_cosim.contour.gcode import Program
from twin_cosim.contour.interpolation import PlannedMotion, plan_program
from twin_cosim.contour.lockstep import AxisRun, run_axes_fast, run_axes_reference
from twin_cosim.contour.path import distance_to_path
from twin_cosim.metrics import UM_PER_M, compute_metrics
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid, interpolate
from twin_cosim.scenario.machine import MachineScenario


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
    contour : pandas.DataFrame
        One row per position-loop sample: ``t`` (s), ``<axis>_ref`` and ``<axis>`` (m) of each
        axis (lower-case names), ``contour_error`` (m, distance of the actual position to the
        programmed path).
    """

    axes: dict[str, pd.DataFrame]
    contour: pd.DataFrame


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


def contour_frame(records: dict[str, pd.DataFrame], motion: PlannedMotion) -> pd.DataFrame:
    """The contour record of per-axis records (see :class:`MachineRecord`)."""
    first = next(iter(records.values()))
    frame = {"t": first["t"].to_numpy()}
    actual = np.zeros((len(first), 3))
    for name, record in records.items():
        frame[f"{name.lower()}_ref"] = record["x_ref"].to_numpy()
        frame[name.lower()] = record["x"].to_numpy()
        actual[:, "XYZ".index(name)] = record["x"].to_numpy()
    frame["contour_error"] = distance_to_path(motion.elements, actual)
    return pd.DataFrame(frame)


def run_machine(
    machine: MachineScenario,
    motion: PlannedMotion,
    plants: MachinePlants,
    fast: bool = True,
    abort_error: float = math.inf,
) -> MachineRecord:
    """Run a planned motion on every axis in lockstep.

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
    records = (run_axes_fast if fast else run_axes_reference)(runs, abort_error)
    return MachineRecord(records, contour_frame(records, motion))


def contour_metrics(record: MachineRecord) -> dict[str, float]:
    """Contour error over the run: ``contour_error_max_um`` and ``contour_error_rms_um`` (um)."""
    error = record.contour["contour_error"].to_numpy() * UM_PER_M
    return {
        "contour_error_max_um": float(np.max(error)),
        "contour_error_rms_um": float(np.sqrt(np.mean(error**2))),
    }


def axis_metrics(record: MachineRecord) -> dict[str, dict[str, float]]:
    """The single-axis metrics of each axis (E_pk um, ITAE um.s^2, IAU A.s, ...) by name."""
    return {name: compute_metrics(frame).as_dict() for name, frame in record.axes.items()}


def run_program(
    machine: MachineScenario,
    program: Program,
    plants: MachinePlants,
    fast: bool = True,
    abort_error: float = math.inf,
) -> tuple[MachineRecord, PlannedMotion]:
    """Run a part program on the machine: its planned motion, then the lockstep run.

    The program starts at the machine's origin (every axis at 0 m); ``abort_error`` as for
    :func:`run_machine` (m).
    """
    limits = {axis.name: axis.limits for axis in machine.axes}
    motion = plan_program(program, limits, machine.sample_period, machine.settle)
    return run_machine(machine, motion, plants, fast, abort_error), motion
