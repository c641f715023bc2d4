"""The master of a machine: several axes, each its own plant FMU instance, stepped in lockstep.

Every speed-loop period all axes advance together: per axis its speed loop, set its inputs,
doStep(t_k, speed_period), read its outputs; every position period the position loops of all
axes run first on their latest measured positions. Each axis runs the single-axis controller
(:func:`twin_cosim.controller.position_loop`, :func:`twin_cosim.controller.speed_loop`) with its
own parameter vector; the axes share the CNC's rates.

Two paths give the same trajectories, as for one axis (:mod:`twin_cosim.cosim`):
:func:`run_axes_reference` through fmpy in plain Python, :func:`run_axes_fast` in a compiled loop
(:mod:`twin_cosim.loops`) calling each instance's fmi2 C functions. The record of each axis has
the single-axis columns (:data:`twin_cosim.cosim.RECORD_COLUMNS`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from twin_cosim import controller
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.cosim import (
    INPUT_NAMES,
    OUTPUT_NAMES,
    RECORD_COLUMNS,
    FastCalls,
    RunAborted,
)
from twin_cosim.loops import ABORTED, compiled_loops
from twin_cosim.plant import Plant, PlantError
from twin_cosim.reference import ReferenceGrid

_IN_CURRENT = INPUT_NAMES.index("current_cmd")
_OUT_ANGLE, _OUT_SPEED, _OUT_POSITION = (
    OUTPUT_NAMES.index(n) for n in ("motor_angle", "motor_speed", "load_position")
)
_CURRENT = RECORD_COLUMNS.index("current")


@dataclass(frozen=True)
class AxisRun:
    """One axis of a lockstep run.

    Attributes
    ----------
    name : str
        Axis name (``X``, ``Y``, ``Z``).
    plant : Plant
        The axis' own FMU instance (reset and parametrised by the run).
    grid : ReferenceGrid
        The axis' reference on the position-loop grid (m, m/s, m/s^2).
    tuned, settings
        The axis' controller.
    plant_parameters : dict
        FMU parameter values by name.
    """

    name: str
    plant: Plant
    grid: ReferenceGrid
    tuned: TunedParameters
    settings: ControllerSettings
    plant_parameters: Mapping[str, float] = field(default_factory=dict)


def _check_lockstep(axes: Sequence[AxisRun]) -> tuple[float, int, int]:
    """(position period s, speed steps per position step, samples) shared by all axes."""
    if not axes:
        raise ValueError("a lockstep run needs at least one axis")
    first = axes[0]
    period = first.settings.position_period
    ratio = first.settings.speed_steps_per_position_step
    samples = len(first.grid.position)
    for axis in axes:
        same = (
            axis.settings.position_period == period
            and axis.settings.speed_steps_per_position_step == ratio
            and axis.grid.period == period
            and len(axis.grid.position) == samples
        )
        if not same:
            raise ValueError(
                f"axis {axis.name}: its rates or reference length differ from axis {first.name}'s"
                " (position period, speed period and samples must be the same on every axis)"
            )
    if len({id(axis.plant) for axis in axes}) != len(axes):
        raise ValueError("every axis needs its own plant instance")
    return period, ratio, samples


def _raise_aborted(axis: str, abort_error: float, t: float) -> None:
    aborted = RunAborted(
        f"axis {axis}: |x_ref - x| exceeded {abort_error * 1e6:g} um at t = {t:.4f} s"
    )
    aborted.time_s = t
    raise aborted


def _frames(axes: Sequence[AxisRun], record: np.ndarray) -> dict[str, pd.DataFrame]:
    return {
        axis.name: pd.DataFrame(record[a], columns=list(RECORD_COLUMNS))
        for a, axis in enumerate(axes)
    }


def run_axes_reference(
    axes: Sequence[AxisRun], abort_error: float = math.inf
) -> dict[str, pd.DataFrame]:
    """Lockstep run in plain Python through fmpy (the readable reference path).

    Parameters
    ----------
    axes
        The axes, each with its own plant instance; same rates and reference length.
    abort_error
        Stop with :class:`~twin_cosim.cosim.RunAborted` once an axis' |x_ref - x| exceeds this
        (m).

    Returns
    -------
    dict
        Axis name -> record, one row per position-loop sample (columns
        :data:`~twin_cosim.cosim.RECORD_COLUMNS`).
    """
    period, ratio, samples = _check_lockstep(axes)
    h = period / ratio
    p = [controller.parameter_vector(a.tuned, a.settings) for a in axes]
    s = [controller.initial_state() for _ in axes]
    vr_in = [[a.plant.value_reference(n) for n in INPUT_NAMES] for a in axes]
    vr_out = [[a.plant.value_reference(n) for n in OUTPUT_NAMES] for a in axes]
    for axis in axes:
        axis.plant.start_run(axis.plant_parameters)

    def read(a: int) -> list[float]:
        fmu = axes[a].plant.fmu
        return axes[a].plant.call("fmi2GetReal", fmu.getReal, vr_out[a])

    outputs = [read(a) for a in range(len(axes))]
    record = np.empty((len(axes), samples, len(RECORD_COLUMNS)))
    for i in range(samples):
        t = i * period
        for a, axis in enumerate(axes):
            g, out = axis.grid, outputs[a]
            position = out[_OUT_POSITION]
            controller.position_loop(
                p[a], s[a], t, g.position[i], g.velocity[i], g.acceleration[i], position
            )
            record[a, i, :_CURRENT] = (
                t,
                g.position[i],
                g.velocity[i],
                position,
                g.position[i] - position,
                out[_OUT_ANGLE],
                out[_OUT_SPEED],
                s[a][controller.SPEED_CMD],
            )
            if abs(g.position[i] - position) > abort_error:
                _raise_aborted(axis.name, abort_error, t)
        current_sum = [0.0] * len(axes)
        for j in range(ratio):
            k = i * ratio + j
            for a, axis in enumerate(axes):
                current = controller.speed_loop(p[a], s[a], k * h, outputs[a][_OUT_SPEED])
                current_sum[a] += current
                inputs = [0.0] * len(INPUT_NAMES)
                inputs[_IN_CURRENT] = current
                fmu = axis.plant.fmu
                axis.plant.call("fmi2SetReal", fmu.setReal, vr_in[a], inputs)
                axis.plant.call("fmi2DoStep", fmu.doStep, k * h, h)
                outputs[a] = read(a)
        for a in range(len(axes)):
            record[a, i, _CURRENT] = current_sum[a] / ratio
    return _frames(axes, record)


def run_axes_fast(
    axes: Sequence[AxisRun], abort_error: float = math.inf
) -> dict[str, pd.DataFrame]:
    """Lockstep run in the compiled loop (:func:`twin_cosim.loops.kernels.lockstep_loop`);
    arguments and records as :func:`run_axes_reference`."""
    period, ratio, samples = _check_lockstep(axes)
    calls = [FastCalls(a.plant) for a in axes]
    p = np.stack([controller.parameter_vector(a.tuned, a.settings) for a in axes])
    s = np.stack([controller.initial_state() for _ in axes])
    record = np.empty((len(axes), samples, len(RECORD_COLUMNS)))
    for axis in axes:
        axis.plant.start_run(axis.plant_parameters)
    status, step, at = compiled_loops().lockstep_loop(
        np.array([c.set_real for c in calls], dtype=np.int64),
        np.array([c.do_step for c in calls], dtype=np.int64),
        np.array([c.get_real for c in calls], dtype=np.int64),
        np.array([a.plant.fmu.component for a in axes], dtype=np.int64),
        np.stack([c.vr_in for c in calls]),
        np.stack([c.vr_out for c in calls]),
        p,
        s,
        period,
        ratio,
        np.stack([a.grid.position for a in axes]),
        np.stack([a.grid.velocity for a in axes]),
        np.stack([a.grid.acceleration for a in axes]),
        abort_error,
        record,
    )
    if status == ABORTED:
        _raise_aborted(axes[at].name, abort_error, step * period / ratio)
    if status != 0:
        plant = axes[at].plant
        log = "\n  ".join(plant.messages[-10:]) or "(no message logged)"
        raise PlantError(
            f"axis {axes[at].name}: {plant.fmu_path}: fmi2 call failed with status {status} at "
            f"speed-loop step {step} (t = {max(step, 0) * period / ratio:.6f} s). FMU log:\n  {log}"
        )
    return _frames(axes, record)
