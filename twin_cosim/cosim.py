"""The co-simulation master: the P-PI cascade stepping a plant FMU at the CNC's rates.

Two paths give the same trajectory:

- :func:`run_reference_path`: a plain Python loop through fmpy's ``FMU2Slave`` calls; the readable
  reference.
- :func:`run_fast_path` (the default): the same controller functions compiled by numba (ahead
  of time when built, see :mod:`twin_cosim.loops`), calling fmi2SetReal / fmi2DoStep /
  fmi2GetReal through their C function pointers from inside the compiled loop.

Per speed-loop sample k (t_k = k * speed_period): current from the speed loop, set the inputs,
doStep(t_k, speed_period), read the outputs. Every ``position_period`` the position loop runs
first on the latest measured position. The record holds one row per position-loop sample.
"""

from __future__ import annotations

import ctypes
import functools
import math
import weakref
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from twin_cosim import controller
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.loops import ABORTED, compiled_loops
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS, Plant, PlantError
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario

if TYPE_CHECKING:
    import pandas as pd

RECORD_COLUMNS = (
    "t",  # s, position-loop sample time
    "x_ref",  # m, reference carriage position
    "v_ref",  # m/s, reference carriage speed
    "x",  # m, measured carriage position (linear scale, noise included)
    "error",  # m, x_ref - x
    "motor_angle",  # rad
    "motor_speed",  # rad/s
    "speed_cmd",  # rad/s, speed command of the position loop (without reversal pulse)
    "current",  # A, mean current command over the following position period
)
RECORD_UNITS = {
    "t": "s",
    "x_ref": "m",
    "v_ref": "m/s",
    "x": "m",
    "error": "m",
    "motor_angle": "rad",
    "motor_speed": "rad/s",
    "speed_cmd": "rad/s",
    "current": "A",
}
INPUT_NAMES = CONTRACT_INPUTS
OUTPUT_NAMES = CONTRACT_OUTPUTS
# Positions of the inputs and outputs in the vectors of fmi2SetReal and fmi2GetReal.
_IN_CURRENT, _IN_DISTURBANCE = (INPUT_NAMES.index(n) for n in ("current_cmd", "disturbance_torque"))
_OUT_ANGLE, _OUT_SPEED, _OUT_POSITION = (
    OUTPUT_NAMES.index(n) for n in ("motor_angle", "motor_speed", "load_position")
)
_T, _X_REF, _V_REF, _X, _ERROR, _ANGLE, _SPEED, _SPEED_CMD, _CURRENT = range(len(RECORD_COLUMNS))


class RunAborted(RuntimeError):
    """The position error left the allowed band: the closed loop is unstable or runs away.

    ``time_s``: the position-loop sample time (s) at which the run stopped.
    """

    time_s: float = math.nan


def _value_references(plant: Plant, names: tuple[str, ...]) -> np.ndarray:
    return np.array([plant.value_reference(n) for n in names], dtype=np.uint32)


def _check_inputs(grid: ReferenceGrid, signal: np.ndarray | None, what: str) -> np.ndarray:
    """An input signal per position sample (zeros when None), checked for shape and finiteness."""
    n = len(grid.position)
    if signal is None:
        return _zeros(n)
    signal = np.ascontiguousarray(signal, dtype=np.float64)
    if signal.shape != (n,) or not np.all(np.isfinite(signal)):
        raise ValueError(f"{what} must be {n} finite values, one per position sample")
    return signal


@functools.lru_cache(maxsize=8)
def _zeros(n: int) -> np.ndarray:
    """``n`` zeros, read-only: a signal that is off, made once per length (the loops only read
    their inputs)."""
    zeros = np.zeros(n)
    zeros.flags.writeable = False
    return zeros


def _contiguous(values: np.ndarray) -> np.ndarray:
    """``values`` as C-contiguous float64 (the compiled loops' layout; no copy when it is)."""
    return np.ascontiguousarray(values, dtype=np.float64)


def _raise_aborted(abort_error: float, t: float) -> None:
    aborted = RunAborted(f"|x_ref - x| exceeded {abort_error * 1e6:g} um at t = {t:.4f} s")
    aborted.time_s = t
    raise aborted


def run_reference_path(
    plant: Plant,
    grid: ReferenceGrid,
    tuned: TunedParameters,
    settings: ControllerSettings,
    plant_parameters: Mapping[str, float] | None = None,
    disturbance: np.ndarray | None = None,
    abort_error: float = math.inf,
    command_offset: np.ndarray | None = None,
) -> RunRecord:
    """Closed-loop run in plain Python through fmpy (the readable reference path).

    Parameters
    ----------
    plant
        The plant; reset and parametrised here.
    grid
        Reference on the position-loop grid (its period must equal settings.position_period).
    tuned, settings
        Controller parameters.
    plant_parameters
        FMU parameter values by name.
    disturbance
        Disturbance torque (N.m) per position sample; zero when None.
    abort_error
        Stop with :class:`RunAborted` once |x_ref - x| exceeds this (m).
    command_offset
        Signal added to the controller's output (after its limit) before the plant's
        ``current_cmd`` input, per position sample (A, or the command's unit); zero when None.
        The record's ``current`` is the controller's output without it.

    Returns
    -------
    RunRecord
        One row per position-loop sample, columns :data:`RECORD_COLUMNS`.
    """
    disturbance = _check_inputs(grid, disturbance, "disturbance torque")
    command_offset = _check_inputs(grid, command_offset, "command offset")
    p = controller.parameter_vector(tuned, settings)
    s = controller.initial_state(len(settings.filters))
    ratio = settings.speed_steps_per_position_step
    h = settings.speed_period
    vr_in = [int(v) for v in _value_references(plant, INPUT_NAMES)]
    vr_out = [int(v) for v in _value_references(plant, OUTPUT_NAMES)]
    plant.start_run(plant_parameters)
    fmu = plant.fmu

    def read_outputs() -> tuple[float, float, float]:
        values = plant.call("fmi2GetReal", fmu.getReal, vr_out)
        return values[_OUT_SPEED], values[_OUT_POSITION], values[_OUT_ANGLE]

    speed, position, angle = read_outputs()
    record = np.empty((len(grid.position), len(RECORD_COLUMNS)))
    for i in range(len(grid.position)):
        t = i * grid.period
        controller.position_loop(
            p, s, t, grid.position[i], grid.velocity[i], grid.acceleration[i], position
        )
        record[i, :_CURRENT] = (
            t,
            grid.position[i],
            grid.velocity[i],
            position,
            grid.position[i] - position,
            angle,
            speed,
            s[controller.SPEED_CMD],
        )
        if abs(grid.position[i] - position) > abort_error:
            _raise_aborted(abort_error, t)
        current_sum = 0.0
        inputs = [0.0] * len(vr_in)
        inputs[_IN_DISTURBANCE] = disturbance[i]  # both held over the position period
        offset = command_offset[i]
        for j in range(ratio):
            k = i * ratio + j
            current = controller.speed_loop(p, s, k * h, speed)
            current_sum += current
            inputs[_IN_CURRENT] = current + offset
            plant.call("fmi2SetReal", fmu.setReal, vr_in, inputs)
            plant.call("fmi2DoStep", fmu.doStep, k * h, h)
            speed, position, angle = read_outputs()
        record[i, _CURRENT] = current_sum / ratio
    return RunRecord(record, RECORD_COLUMNS, RECORD_UNITS)


class FastCalls:
    """Addresses of one loaded plant's fmi2 C functions (ints) and its value references, for
    the compiled loops."""

    def __init__(self, plant: Plant) -> None:
        dll = plant.fmu.dll
        address = {
            name: ctypes.cast(getattr(dll, name), ctypes.c_void_p).value
            for name in ("fmi2SetReal", "fmi2DoStep", "fmi2GetReal")
        }
        self.set_real: int = address["fmi2SetReal"]
        self.do_step: int = address["fmi2DoStep"]
        self.get_real: int = address["fmi2GetReal"]
        self.vr_in = _value_references(plant, INPUT_NAMES)
        self.vr_out = _value_references(plant, OUTPUT_NAMES)


_FAST_CALLS: weakref.WeakKeyDictionary[Plant, FastCalls] = weakref.WeakKeyDictionary()


def fast_calls(plant: Plant) -> FastCalls:
    """The C function pointers of ``plant``, made once per plant instance."""
    calls = _FAST_CALLS.get(plant)
    if calls is None:
        calls = _FAST_CALLS[plant] = FastCalls(plant)
    return calls


def raise_plant_error(plant: Plant, status: int, step: int, speed_period: float) -> None:
    """PlantError for a failed fmi2 call at speed-loop ``step``, with the FMU's log."""
    log = "\n  ".join(plant.messages[-10:]) or "(no message logged)"
    raise PlantError(
        f"{plant.fmu_path}: fmi2 call failed with status {status} at speed-loop step {step} "
        f"(t = {max(step, 0) * speed_period:.6f} s). FMU log:\n  {log}"
    )


def run_fast_path(
    plant: Plant,
    grid: ReferenceGrid,
    tuned: TunedParameters,
    settings: ControllerSettings,
    plant_parameters: Mapping[str, float] | None = None,
    disturbance: np.ndarray | None = None,
    abort_error: float = math.inf,
    command_offset: np.ndarray | None = None,
) -> RunRecord:
    """Closed-loop run in the compiled loop (:func:`twin_cosim.loops.kernels.closed_loop`);
    arguments and record as :func:`run_reference_path`."""
    disturbance = _check_inputs(grid, disturbance, "disturbance torque")
    command_offset = _check_inputs(grid, command_offset, "command offset")
    calls = fast_calls(plant)
    p = controller.parameter_vector(tuned, settings)
    s = controller.initial_state(len(settings.filters))
    record = np.empty((len(grid.position), len(RECORD_COLUMNS)))
    plant.start_run(plant_parameters)
    status, step = compiled_loops().closed_loop(
        calls.set_real,
        calls.do_step,
        calls.get_real,
        plant.fmu.component,
        calls.vr_in,
        calls.vr_out,
        p,
        s,
        grid.period,
        settings.speed_steps_per_position_step,
        _contiguous(grid.position),
        _contiguous(grid.velocity),
        _contiguous(grid.acceleration),
        disturbance,
        command_offset,
        abort_error,
        record,
    )
    if status == ABORTED:
        _raise_aborted(abort_error, step * settings.speed_period)
    if status != 0:
        raise_plant_error(plant, status, step, settings.speed_period)
    return RunRecord(record, RECORD_COLUMNS, RECORD_UNITS)


def run_scenario(
    plant: Plant,
    scenario: Scenario,
    tuned: TunedParameters | None = None,
    fast: bool = True,
    plant_overrides: Mapping[str, float] | None = None,
    abort_error: float = math.inf,
) -> pd.DataFrame:
    """:func:`run_scenario_record` as a pandas DataFrame (same arguments)."""
    return run_scenario_record(plant, scenario, tuned, fast, plant_overrides, abort_error).frame()


def run_scenario_record(
    plant: Plant,
    scenario: Scenario,
    tuned: TunedParameters | None = None,
    fast: bool = True,
    plant_overrides: Mapping[str, float] | None = None,
    abort_error: float = math.inf,
) -> RunRecord:
    """Run a scenario's reference in closed loop; one row per position-loop sample, columns
    :data:`RECORD_COLUMNS`.

    Parameters
    ----------
    plant
        The plant to step (any FMU offering the plant contract).
    scenario
        Reference, controller settings and plant parameters.
    tuned
        Controller parameters; the scenario's own when None.
    fast
        The numba path (default) or the fmpy reference path.
    plant_overrides
        FMU parameters applied on top of the scenario's.
    abort_error
        Stop with :class:`RunAborted` once |x_ref - x| exceeds this (m).

    The scenario's signal conventions apply (``reference.disturbance``): a disturbance that
    enters at the command is added to the controller's output, and the record's ``current``
    includes it when the scenario says the measured command does.
    """
    parameters = {**scenario.plant_parameters, **(plant_overrides or {})}
    run = run_fast_path if fast else run_reference_path
    tuned = tuned or scenario.tuned
    record = run(
        plant,
        scenario.reference,
        tuned,
        scenario.settings,
        parameters,
        scenario.disturbance,
        abort_error,
        scenario.command_disturbance,
    )
    if scenario.command_disturbance is not None and scenario.disturbance_in_record:
        record["current"] += scenario.command_disturbance
    return record
