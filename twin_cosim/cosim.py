"""The co-simulation master: the P-PI cascade stepping the plant FMUs of N axes at the CNC's rates.

Each axis runs the single-axis controller (:func:`twin_cosim.controller.position_loop`,
:func:`twin_cosim.controller.speed_loop`) with its own parameters on its own plant instance; the
axes share the CNC's rates and advance together, position period by position period (one axis
is N = 1). Per position-loop sample i (t_i = i * position_period), axis by axis: the position
loop on the axis' latest measured position and its record row, then the axis' speed-loop samples
k (t_k = k * speed_period): the current from its speed loop, set its inputs, doStep(t_k,
speed_period), read its outputs. The axes do not act on each other: each axis' trajectory is the
one it has alone.

One master, two paths that give the same trajectories:

- compiled (the default): :func:`twin_cosim.loops.kernels.master`, the same controller functions
  compiled by numba (ahead of time when built, see :mod:`twin_cosim.loops`), calling each
  instance's SetReal / DoStep / GetReal (FMI 2.0: fmi2SetReal ...; FMI 3.0: fmi3SetFloat64
  ...) through their C function pointers;
- reference: :func:`_step_reference`, a plain Python loop through fmpy's ``FMU2Slave`` or
  ``FMU3Slave`` calls; the readable one.

The options of a run are signals injected into an axis' loops (:class:`Injections`: a load
torque, a current added to the controller's command, a speed or position setpoint offset, noise
on the measured speed), and a record per speed-loop sample beside the one per position-loop
sample. What runs on the master: :func:`run_scenario` (one axis: a scenario's reference and its
disturbances), a machine's axes (:mod:`twin_cosim.contour.machine_run`), the frequency-response
measurement (:mod:`twin_cosim.frequency.measurement`). An option is an array of the compiled
master's one signature, empty when off (a branch that goes the same way through a whole run);
another (a command read from an array in place of the controller's, for an open-loop plant; a
record of the plant's outputs per speed-loop sample) joins the same way.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from twin_cosim import controller
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.loops import ABORTED
from twin_cosim.loops.ahead import compiled_loops
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS, Plant, PlantError
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario

RECORD_COLUMNS = (
    "t",  # s, position-loop sample time
    "x_ref",  # m, reference carriage position
    "v_ref",  # m/s, reference carriage speed
    "x",  # m, measured carriage position (linear scale, noise included)
    "error",  # m, x_ref - x (the position setpoint - x, with a position injection)
    "motor_angle",  # rad
    "motor_speed",  # rad/s
    "speed_cmd",  # rad/s, speed command of the position loop (without reversal pulse)
    "current",  # A, mean current command of the controller over the following position period
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
SPEED_LOOP_COLUMNS = (
    "speed_setpoint",  # rad/s, the speed loop's setpoint, a speed injection included
    "speed",  # rad/s, the motor speed the speed loop read, its noise included
    "current",  # A, the current command the plant received, a current injection included
)
SPEED_LOOP_UNITS = {"speed_setpoint": "rad/s", "speed": "rad/s", "current": "A"}
# Positions of the inputs and outputs in the vectors of SetReal and GetReal, and of the
# record's columns.
_IN_CURRENT, _IN_DISTURBANCE = (
    CONTRACT_INPUTS.index(n) for n in ("current_cmd", "disturbance_torque")
)
_OUT_ANGLE, _OUT_SPEED, _OUT_POSITION = (
    CONTRACT_OUTPUTS.index(n) for n in ("motor_angle", "motor_speed", "load_position")
)
_CURRENT = RECORD_COLUMNS.index("current")


class RunAborted(RuntimeError):
    """The position error left the allowed band: the closed loop is unstable or runs away.

    ``time_s``: the position-loop sample time (s) at which the run stopped.
    """

    time_s: float = math.nan


@dataclass(frozen=True)
class Injections:
    """Signals injected into an axis' loops; each None when off (and then no operation of the
    loop touches it).

    Attributes
    ----------
    load_torque : numpy.ndarray or None
        The plant's ``disturbance_torque`` input per speed-loop sample, N.m.
    current : numpy.ndarray or None
        Added to the controller's current command (after its limit) before the plant's
        ``current_cmd`` input, per speed-loop sample (A, or the command's unit). The record's
        ``current`` is the controller's command without it; the speed-loop record's with it.
    speed : numpy.ndarray or None
        Added to the speed loop's setpoint per speed-loop sample, rad/s.
    position : numpy.ndarray or None
        Added to the position loop's setpoint per position-loop sample, m; the record's
        ``error`` is then the setpoint minus the measured position.
    speed_noise : numpy.ndarray or None
        Added to the motor speed the speed loop reads per speed-loop sample, rad/s.
    """

    load_torque: np.ndarray | None = None
    current: np.ndarray | None = None
    speed: np.ndarray | None = None
    position: np.ndarray | None = None
    speed_noise: np.ndarray | None = None


# Each injection's rate: True per speed-loop sample, False per position-loop sample.
_AT_SPEED_RATE = {
    "load_torque": True,
    "current": True,
    "speed": True,
    "position": False,
    "speed_noise": True,
}


@dataclass(frozen=True)
class AxisRun:
    """One axis of a run.

    Attributes
    ----------
    name : str
        Axis name (``X``, ``Y``, ``Z``; a single axis' name is not shown).
    plant : Plant
        The axis' own FMU instance (reset and parametrised by the run).
    grid : ReferenceGrid
        The axis' reference on the position-loop grid (m, m/s, m/s^2).
    tuned, settings
        The axis' controller.
    plant_parameters : dict
        FMU parameter values by name.
    injections : Injections
        Signals injected into its loops (none by default).
    """

    name: str
    plant: Plant
    grid: ReferenceGrid
    tuned: TunedParameters
    settings: ControllerSettings
    plant_parameters: Mapping[str, float] = field(default_factory=dict)
    injections: Injections = field(default_factory=Injections)


@dataclass(frozen=True)
class AxisRecord:
    """What the master recorded of one axis.

    Attributes
    ----------
    position_loop : RunRecord
        One row per position-loop sample, columns :data:`RECORD_COLUMNS`.
    speed_loop : RunRecord or None
        One row per speed-loop sample, columns :data:`SPEED_LOOP_COLUMNS`, when asked for.
    """

    position_loop: RunRecord
    speed_loop: RunRecord | None


@dataclass(frozen=True)
class _Prologue:
    """A run prepared for either path: its axes, rates and band, the controllers' vectors, the
    references and the injections as rows (one per axis), the value references, the records to
    fill; the plants started."""

    axes: Sequence[AxisRun]
    abort_error: float  # m
    period: float  # s, position-loop period
    ratio: int  # speed-loop samples per position-loop sample
    samples: int  # position-loop samples
    p: np.ndarray  # controller parameters, one row per axis (zero-padded)
    s: np.ndarray  # controller states, one row per axis (zero-padded)
    x_ref: np.ndarray  # m
    v_ref: np.ndarray  # m/s
    a_ref: np.ndarray  # m/s^2
    injections: dict[str, np.ndarray]  # by Injections field: rows, or no columns when off
    vr_in: np.ndarray  # value references of the contract's inputs, one row per axis
    vr_out: np.ndarray  # of its outputs
    record: np.ndarray  # (axis, position sample, RECORD_COLUMNS)
    speed_record: np.ndarray  # (axis, speed sample, SPEED_LOOP_COLUMNS), or no samples


def _rates(axes: Sequence[AxisRun]) -> tuple[float, int, int]:
    """(position period s, speed steps per position step, samples) shared by all axes."""
    if not axes:
        raise ValueError("a run needs at least one axis")
    first = axes[0]
    period = first.grid.period
    ratio = first.settings.speed_steps_per_position_step
    samples = len(first.grid.position)
    for axis in axes:
        if axis.grid.period != axis.settings.position_period:
            raise ValueError(
                f"axis {axis.name}: its reference is sampled every {axis.grid.period:g} s, its "
                f"position loop runs every {axis.settings.position_period:g} s; they must be equal"
            )
        same = (
            axis.settings.position_period == first.settings.position_period
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
    if len({axis.name for axis in axes}) != len(axes):
        raise ValueError(f"the axes need names of their own, got {[a.name for a in axes]}")
    return period, ratio, samples


def _rows(values: Sequence[np.ndarray]) -> np.ndarray:
    """Equal-length vectors as the rows of one C-contiguous float64 array (one vector: a view)."""
    if len(values) == 1:
        return np.ascontiguousarray(values[0], dtype=np.float64)[np.newaxis]
    return np.stack([np.asarray(v, dtype=np.float64) for v in values])


def _padded(vectors: Sequence[np.ndarray]) -> np.ndarray:
    """Vectors of possibly different lengths as rows, zero-padded (the controller reads only as
    many filter sections as its parameters name)."""
    rows = np.zeros((len(vectors), max(len(v) for v in vectors)))
    for a, vector in enumerate(vectors):
        rows[a, : len(vector)] = vector
    return rows


def _injections(axes: Sequence[AxisRun], samples: int, ratio: int) -> dict[str, np.ndarray]:
    """Each injection as rows (zeros for an axis without it), or rows of no columns when no
    axis has it; checked for length and finiteness."""
    found = {}
    for name, speed_rate in _AT_SPEED_RATE.items():
        n = samples * ratio if speed_rate else samples
        given = {axis.name: getattr(axis.injections, name) for axis in axes}
        if all(v is None for v in given.values()):
            found[name] = np.empty((len(axes), 0))
            continue
        rows = []
        for axis_name, signal in given.items():
            if signal is None:
                rows.append(np.zeros(n))
                continue
            signal = np.asarray(signal, dtype=np.float64)
            if signal.shape != (n,) or not np.all(np.isfinite(signal)):
                rate = "speed" if speed_rate else "position"
                raise ValueError(
                    f"axis {axis_name}: the {name.replace('_', ' ')} injection must be {n} "
                    f"finite values, one per {rate}-loop sample"
                )
            rows.append(signal)
        found[name] = _rows(rows)
    return found


def _value_references(plant: Plant, names: tuple[str, ...]) -> np.ndarray:
    return np.array([plant.value_reference(n) for n in names], dtype=np.uint32)


def _prologue(axes: Sequence[AxisRun], abort_error: float, speed_loop_record: bool) -> _Prologue:
    """Check the axes, prepare the run and start every axis' plant."""
    period, ratio, samples = _rates(axes)
    injections = _injections(axes, samples, ratio)
    speed_samples = samples * ratio if speed_loop_record else 0
    prologue = _Prologue(
        axes=axes,
        abort_error=abort_error,
        period=period,
        ratio=ratio,
        samples=samples,
        p=_padded([controller.parameter_vector(a.tuned, a.settings) for a in axes]),
        s=_padded([controller.initial_state(len(a.settings.filters)) for a in axes]),
        x_ref=_rows([a.grid.position for a in axes]),
        v_ref=_rows([a.grid.velocity for a in axes]),
        a_ref=_rows([a.grid.acceleration for a in axes]),
        injections=injections,
        vr_in=np.stack([_value_references(a.plant, CONTRACT_INPUTS) for a in axes]),
        vr_out=np.stack([_value_references(a.plant, CONTRACT_OUTPUTS) for a in axes]),
        record=np.empty((len(axes), samples, len(RECORD_COLUMNS))),
        speed_record=np.empty((len(axes), speed_samples, len(SPEED_LOOP_COLUMNS))),
    )
    for axis in axes:
        axis.plant.start_run(axis.plant_parameters)
    return prologue


class FastCalls:
    """Addresses (ints) of one loaded plant's FMI C functions and its FMI version, for the
    compiled master."""

    def __init__(self, plant: Plant) -> None:
        self.version: int = plant.fmi_version
        self.set_real, self.do_step, self.get_real = plant.function_addresses()


_FAST_CALLS: weakref.WeakKeyDictionary[Plant, FastCalls] = weakref.WeakKeyDictionary()


def fast_calls(plant: Plant) -> FastCalls:
    """The C function pointers of ``plant``, made once per plant instance."""
    calls = _FAST_CALLS.get(plant)
    if calls is None:
        calls = _FAST_CALLS[plant] = FastCalls(plant)
    return calls


def _step_compiled(run: _Prologue) -> tuple[int, int, int]:
    """The run in the compiled master; its (status, speed-loop step, axis) as it stopped."""
    axes = run.axes
    calls = [fast_calls(a.plant) for a in axes]
    injected = run.injections
    status, step, at = compiled_loops().master(
        np.array([c.version for c in calls], dtype=np.int64),
        np.array([c.set_real for c in calls], dtype=np.int64),
        np.array([c.do_step for c in calls], dtype=np.int64),
        np.array([c.get_real for c in calls], dtype=np.int64),
        np.array([a.plant.fmu.component for a in axes], dtype=np.int64),
        run.vr_in,
        run.vr_out,
        run.p,
        run.s,
        run.period,
        run.ratio,
        run.x_ref,
        run.v_ref,
        run.a_ref,
        injected["load_torque"],
        injected["current"],
        injected["speed"],
        injected["position"],
        injected["speed_noise"],
        run.abort_error,
        run.record,
        run.speed_record,
    )
    return status, step, at


def _step_reference(run: _Prologue) -> tuple[int, int, int]:
    """The run in plain Python through fmpy (the readable path, the same operations as the
    compiled master); its (status, speed-loop step, axis) as it stopped. A failing FMI call
    raises :class:`~twin_cosim.plant.PlantError` with the FMU's log."""
    axes, record, speed_record = run.axes, run.record, run.speed_record
    h = run.period / run.ratio
    p, s = run.p, run.s
    injected = {name: rows if rows.shape[1] else None for name, rows in run.injections.items()}
    load_torque, at_current = injected["load_torque"], injected["current"]
    at_speed, at_position = injected["speed"], injected["position"]
    speed_noise = injected["speed_noise"]
    recording = speed_record.shape[1] > 0
    vr_in = [[int(v) for v in row] for row in run.vr_in]
    vr_out = [[int(v) for v in row] for row in run.vr_out]

    def read_outputs(a: int) -> list[float]:
        return axes[a].plant.get_reals(vr_out[a])

    outputs = [read_outputs(a) for a in range(len(axes))]
    for i in range(run.samples):
        t = i * run.period
        for a, axis in enumerate(axes):
            pa, sa = p[a], s[a]
            position = outputs[a][_OUT_POSITION]
            setpoint = run.x_ref[a, i]
            if at_position is not None:
                setpoint = setpoint + at_position[a, i]
            controller.position_loop(
                pa, sa, t, setpoint, run.v_ref[a, i], run.a_ref[a, i], position
            )
            record[a, i, :_CURRENT] = (
                t,
                run.x_ref[a, i],
                run.v_ref[a, i],
                position,
                setpoint - position,
                outputs[a][_OUT_ANGLE],
                outputs[a][_OUT_SPEED],
                sa[controller.SPEED_CMD],
            )
            if abs(setpoint - position) > run.abort_error:
                return ABORTED, i * run.ratio, a
            current_sum = 0.0
            inputs = [0.0] * len(CONTRACT_INPUTS)
            for j in range(run.ratio):
                k = i * run.ratio + j
                speed = outputs[a][_OUT_SPEED]
                if speed_noise is not None:
                    speed = speed + speed_noise[a, k]
                command = sa[controller.SPEED_CMD]
                if at_speed is not None:
                    sa[controller.SPEED_CMD] = command + at_speed[a, k]
                if recording:
                    speed_record[a, k, 0] = sa[controller.SPEED_CMD]
                current = controller.speed_loop(pa, sa, k * h, speed)
                if at_speed is not None:
                    sa[controller.SPEED_CMD] = command
                current_sum += current
                if at_current is not None:
                    current = current + at_current[a, k]
                if recording:
                    speed_record[a, k, 1:] = (speed, current)
                inputs[_IN_CURRENT] = current
                if load_torque is not None:
                    inputs[_IN_DISTURBANCE] = load_torque[a, k]
                axis.plant.set_reals(vr_in[a], inputs)
                axis.plant.do_step(k * h, h)
                outputs[a] = read_outputs(a)
            record[a, i, _CURRENT] = current_sum / run.ratio
    return 0, -1, -1


def _raise_stopped(
    axes: Sequence[AxisRun], status: int, step: int, at: int, abort_error: float
) -> None:
    """:class:`RunAborted` or :class:`~twin_cosim.plant.PlantError` for a run that stopped at
    speed-loop ``step`` on axis ``at`` (named when the run has several)."""
    axis = axes[at]
    named = f"axis {axis.name}: " if len(axes) > 1 else ""
    t = max(step, 0) * axis.settings.speed_period
    if status == ABORTED:
        aborted = RunAborted(
            f"{named}|x_ref - x| exceeded {abort_error * 1e6:g} um at t = {t:.4f} s"
        )
        aborted.time_s = t
        raise aborted
    log = "\n  ".join(axis.plant.messages[-10:]) or "(no message logged)"
    raise PlantError(
        f"{named}{axis.plant.fmu_path}: fmi{axis.plant.fmi_version} call failed with status "
        f"{status} at speed-loop "
        f"step {step} (t = {t:.6f} s). FMU log:\n  {log}"
    )


def run_axes(
    axes: Sequence[AxisRun],
    fast: bool = True,
    abort_error: float = math.inf,
    speed_loop_record: bool = False,
) -> dict[str, AxisRecord]:
    """Run the axes together on the master.

    Parameters
    ----------
    axes
        The axes, each with its own plant instance; the same rates and reference length.
    fast
        The compiled path (default) or the fmpy reference path.
    abort_error
        Stop with :class:`RunAborted` once an axis' |x_ref - x| (its position setpoint - x,
        with a position injection) exceeds this (m).
    speed_loop_record
        Record every speed-loop sample too (:attr:`AxisRecord.speed_loop`).

    Returns
    -------
    dict
        Axis name -> what the master recorded of it.

    Raises
    ------
    RunAborted
        An axis' error left the band (the axis named when the run has several).
    PlantError
        An FMI call failed (with the FMU's log).
    """
    run = _prologue(axes, abort_error, speed_loop_record)
    status, step, at = (_step_compiled if fast else _step_reference)(run)
    if status != 0:
        _raise_stopped(axes, status, step, at, abort_error)
    return {
        axis.name: AxisRecord(
            RunRecord(run.record[a], RECORD_COLUMNS, RECORD_UNITS),
            RunRecord(run.speed_record[a], SPEED_LOOP_COLUMNS, SPEED_LOOP_UNITS)
            if speed_loop_record
            else None,
        )
        for a, axis in enumerate(axes)
    }


def run_scenario(
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
        The compiled path (default) or the fmpy reference path.
    plant_overrides
        FMU parameters applied on top of the scenario's.
    abort_error
        Stop with :class:`RunAborted` once |x_ref - x| exceeds this (m).

    The scenario's signal conventions apply (``reference.disturbance``): its disturbance torque
    (N.m) and its disturbance at the command, per position sample, are held over each position
    period; the one at the command is added to the controller's output, and the record's
    ``current`` includes it when the scenario says the measured command does.
    """
    ratio = scenario.settings.speed_steps_per_position_step
    n = len(scenario.reference.position)

    def held(signal: np.ndarray | None, what: str) -> np.ndarray | None:
        """A per-position-sample signal held over each position period (None stays None)."""
        if signal is None:
            return None
        signal = np.asarray(signal, dtype=np.float64)
        if signal.shape != (n,) or not np.all(np.isfinite(signal)):
            raise ValueError(f"{what} must be {n} finite values, one per position sample")
        return np.repeat(signal, ratio)

    axis = AxisRun(
        scenario.name,
        plant,
        scenario.reference,
        tuned or scenario.tuned,
        scenario.settings,
        {**scenario.plant_parameters, **(plant_overrides or {})},
        Injections(
            load_torque=held(scenario.disturbance, "disturbance torque"),
            current=held(scenario.command_disturbance, "command disturbance"),
        ),
    )
    record = run_axes([axis], fast, abort_error)[axis.name].position_loop
    if scenario.command_disturbance is not None and scenario.disturbance_in_record:
        record["current"] += scenario.command_disturbance
    return record
