"""The compiled master: the P-PI cascade stepping the plant FMUs of N axes through their FMI C
functions (FMI 2.0 or FMI 3.0, per axis).

One plain Python function over numbers and arrays (:func:`master`), compiled by numba: just in
time here (with numba's on-disk cache), or ahead of time into a shared library by
:mod:`twin_cosim.loops.ahead` (the same function, the same machine-code semantics, loaded
without numba). Callers reach it through :func:`twin_cosim.loops.ahead.compiled_loops`, which
picks the shared library when it is built for these sources; :mod:`twin_cosim.cosim` prepares
its arguments.

The FMI functions are called by address (:func:`real_call`, :func:`do_step` for FMI 2.0;
:func:`float64_call`, :func:`do_step3` for FMI 3.0): the addresses of ``fmi2SetReal``,
``fmi2DoStep`` and ``fmi2GetReal`` (or ``fmi3SetFloat64``, ``fmi3DoStep``, ``fmi3GetFloat64``) and
the instance handle are plain integers, so that the signature holds only numbers and arrays and
compiles ahead as well as just in time. Each call returns the status as an integer (FMI 2.0 and
3.0 number theirs alike: 0 OK, 1 warning, 2 discard, 3 error, 4 fatal); the master checks it.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from twin_cosim import controller, loops, plant
from twin_cosim.loops import ABORTED, FMI2_OK_OR_WARNING
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS

IN_CURRENT, IN_DISTURBANCE = (
    CONTRACT_INPUTS.index(n) for n in ("current_cmd", "disturbance_torque")
)
OUT_ANGLE, OUT_SPEED, OUT_POSITION = (
    CONTRACT_OUTPUTS.index(n) for n in ("motor_angle", "motor_speed", "load_position")
)
SPEED_CMD = controller.SPEED_CMD

_STATUS = ir.IntType(32)  # fmi2Status, an enum
_POINTER = ir.IntType(8).as_pointer()
_REAL_CALL = ir.FunctionType(_STATUS, [_POINTER, _POINTER, ir.IntType(64), _POINTER])
_DO_STEP = ir.FunctionType(_STATUS, [_POINTER, ir.DoubleType(), ir.DoubleType(), _STATUS])
# FMI 3.0: fmi3SetFloat64 / fmi3GetFloat64 take the number of values as well; fmi3DoStep takes
# noSetFMUStatePriorToCurrentPoint as a bool and returns four values through pointers.
_BOOL = ir.IntType(8)
_FLOAT64_CALL = ir.FunctionType(
    _STATUS, [_POINTER, _POINTER, ir.IntType(64), _POINTER, ir.IntType(64)]
)
_DO_STEP3 = ir.FunctionType(
    _STATUS,
    [_POINTER, ir.DoubleType(), ir.DoubleType(), _BOOL, _POINTER, _POINTER, _POINTER, _POINTER],
)
FMI3 = 3  # an axis' FMI version, as the master's ``versions`` give it


_VALUES_SIGNATURE = types.int64(types.intp, types.intp, types.intp, types.intp, types.intp)


def _values_codegen(function_type: ir.FunctionType, value_count: bool):  # type: ignore[no-untyped-def]
    """The code of a call of a Set/Get function of real values at an address: (instance, value
    references, count, values), and the count of values again when ``value_count`` (FMI 3.0)."""

    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        function = builder.inttoptr(args[0], function_type.as_pointer())
        component_, references_, count_, values_ = args[1:]
        arguments = [
            builder.inttoptr(component_, _POINTER),
            builder.inttoptr(references_, _POINTER),
            count_,
            builder.inttoptr(values_, _POINTER),
        ]
        if value_count:
            arguments.append(count_)
        return builder.sext(builder.call(function, arguments), ir.IntType(64))

    return codegen


@intrinsic
def real_call(typingctx, address, component, references, count, values):  # type: ignore[no-untyped-def]
    """``fmi2SetReal`` or ``fmi2GetReal`` at ``address``: (instance, value references (uint32
    pointer), count, values (float64 pointer)) -> fmi2Status; every argument an integer."""
    return _VALUES_SIGNATURE, _values_codegen(_REAL_CALL, value_count=False)


@intrinsic
def do_step(typingctx, address, component, time, step, no_prior_state):  # type: ignore[no-untyped-def]
    """``fmi2DoStep`` at ``address``: (instance, communication point (s), step size (s),
    noSetFMUStatePriorToCurrentPoint) -> fmi2Status."""
    signature = types.int64(types.intp, types.intp, types.float64, types.float64, types.intp)

    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        function = builder.inttoptr(args[0], _DO_STEP.as_pointer())
        status = builder.call(
            function,
            [
                builder.inttoptr(args[1], _POINTER),
                args[2],
                args[3],
                builder.trunc(args[4], _STATUS),
            ],
        )
        return builder.sext(status, ir.IntType(64))

    return signature, codegen


@intrinsic
def float64_call(typingctx, address, component, references, count, values):  # type: ignore[no-untyped-def]
    """``fmi3SetFloat64`` or ``fmi3GetFloat64`` at ``address``: (instance, value references
    (uint32 pointer), count, values (float64 pointer), count of values: the same) -> status."""
    return _VALUES_SIGNATURE, _values_codegen(_FLOAT64_CALL, value_count=True)


@intrinsic
def do_step3(typingctx, address, component, time, step, scratch):  # type: ignore[no-untyped-def]
    """``fmi3DoStep`` at ``address``: (instance, communication point (s), step size (s),
    ``scratch``: the address of 16 bytes that receive eventHandlingNeeded, terminateSimulation,
    earlyReturn (a byte each, at 0, 1, 2) and lastSuccessfulTime (a double, at 8)) -> status.
    noSetFMUStatePriorToCurrentPoint is true: the master never sets a state back."""
    signature = types.int64(types.intp, types.intp, types.float64, types.float64, types.intp)

    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        function = builder.inttoptr(args[0], _DO_STEP3.as_pointer())
        base = args[4]
        flags = [
            builder.inttoptr(builder.add(base, ir.Constant(ir.IntType(64), offset)), _POINTER)
            for offset in (0, 1, 2, 8)
        ]
        status = builder.call(
            function,
            [
                builder.inttoptr(args[1], _POINTER),
                args[2],
                args[3],
                ir.Constant(_BOOL, 1),
                *flags,
            ],
        )
        return builder.sext(status, ir.IntType(64))

    return signature, codegen


# The controller's functions compiled; the master inlines them.
position_loop = numba.njit(cache=True)(controller.position_loop)
speed_loop = numba.njit(cache=True)(controller.speed_loop)


@numba.njit(cache=True)
def exchange(
    version,
    set_real,
    step,
    get_real,
    component,
    vr_in,
    inputs,
    n_in,
    vr_out,
    outputs,
    n_out,
    t,
    h,
    scratch,
):  # pragma: no cover - compiled
    """Set the ``n_in`` inputs, doStep(t, h) (s), read the ``n_out`` outputs (value references
    and values at the addresses ``vr_in``, ``inputs``, ``vr_out``, ``outputs``) through the FMI
    ``version``'s functions (``scratch``: 16 bytes for fmi3DoStep's results); the first failing
    status, or the last one."""
    if version == FMI3:
        status = float64_call(set_real, component, vr_in, n_in, inputs)
        if status > FMI2_OK_OR_WARNING:
            return status
        status = do_step3(step, component, t, h, scratch)
        if status > FMI2_OK_OR_WARNING:
            return status
        return float64_call(get_real, component, vr_out, n_out, outputs)
    status = real_call(set_real, component, vr_in, n_in, inputs)
    if status > FMI2_OK_OR_WARNING:
        return status
    status = do_step(step, component, t, h, 1)
    if status > FMI2_OK_OR_WARNING:
        return status
    return real_call(get_real, component, vr_out, n_out, outputs)


@numba.njit(cache=True)
def master(
    versions,
    set_reals,
    steps,
    get_reals,
    components,
    vr_in,
    vr_out,
    p,
    s,
    period,
    ratio,
    x_ref,
    v_ref,
    a_ref,
    load_torque,
    at_current,
    at_speed,
    at_position,
    speed_noise,
    abort_error,
    record,
    speed_record,
):  # pragma: no cover - compiled
    """Step N axes together, each its own plant instance, with the options of a run.

    Per position-loop sample i (t = i * period), axis by axis: the position loop on the axis'
    latest measured position, its record row, then its speed-loop samples k = i * ratio + j
    (h = period / ratio): the speed loop, set the inputs, doStep(k h, h), read the outputs. The
    axes do not act on each other, so each axis' trajectory is that of a lockstep run; the run
    stops at the first axis (in order) whose error leaves the band at a position sample.

    Parameters
    ----------
    versions
        Per axis: the FMI version of its plant (2 or 3).
    set_reals, steps, get_reals, components
        Per axis: the addresses of the version's SetReal (fmi2SetReal or fmi3SetFloat64), DoStep
        and GetReal (fmi2GetReal or fmi3GetFloat64), and the instance.
    vr_in, vr_out
        Per axis: the value references of the contract's inputs and outputs.
    p, s
        Per axis: the controller's parameter and state vectors (``s`` is updated).
    period, ratio
        Position-loop period (s), speed-loop samples per position-loop sample.
    x_ref, v_ref, a_ref
        Per axis and position sample: reference position (m), speed (m/s), acceleration (m/s^2).
    load_torque
        Per axis and speed sample: the disturbance torque input (N.m); none (no columns): the
        input stays 0.
    at_current
        Per axis and speed sample: added to the controller's current command before the plant
        (A); none: the command as it is.
    at_speed
        Per axis and speed sample: added to the speed loop's setpoint (rad/s); none: nothing.
    at_position
        Per axis and position sample: added to the position loop's setpoint (m); the record's
        ``error`` is then the setpoint minus the position; none: nothing.
    speed_noise
        Per axis and speed sample: added to the motor speed the speed loop reads (rad/s); none:
        the speed as measured.
    abort_error
        Stop (status :data:`ABORTED`) once an axis' |setpoint - position| exceeds this (m).
    record
        Filled: per axis and position sample the columns of ``cosim.RECORD_COLUMNS``.
    speed_record
        Filled when it has rows: per axis and speed sample the speed setpoint (rad/s, injection
        included), the speed the loop read (rad/s) and the current command the plant received
        (A); none (no rows): not recorded.

    Returns
    -------
    tuple
        FMI status (0 when the run finished, :data:`ABORTED`), where it stopped (the speed-loop
        step, -1 before the first and when it finished) and the axis (-1 when it finished).
    """
    n_axes = components.shape[0]
    n_in, n_out = vr_in.shape[1], vr_out.shape[1]
    inputs = np.zeros((n_axes, n_in))
    outputs = np.zeros((n_axes, n_out))
    h = period / ratio
    scratch = np.zeros(2)  # fmi3DoStep's four results (never read)
    scratch_address = scratch.ctypes.data
    # The options: off when their arrays are empty; each test below is the same for the whole
    # run. Without any at the speed loop, a speed-loop sample takes the plain branch, one test.
    torque_on = load_torque.shape[1] > 0
    current_on = at_current.shape[1] > 0
    speed_on = at_speed.shape[1] > 0
    position_on = at_position.shape[1] > 0
    noise_on = speed_noise.shape[1] > 0
    recording = speed_record.shape[1] > 0
    plain = not (torque_on or current_on or speed_on or noise_on or recording)
    for a in range(n_axes):
        axis_vr_out = vr_out.ctypes.data + a * vr_out.strides[0]
        axis_outputs = outputs.ctypes.data + a * outputs.strides[0]
        if versions[a] == FMI3:
            status = float64_call(get_reals[a], components[a], axis_vr_out, n_out, axis_outputs)
        else:
            status = real_call(get_reals[a], components[a], axis_vr_out, n_out, axis_outputs)
        if status > FMI2_OK_OR_WARNING:
            return status, -1, a
    # The axis' controller rows: one axis keeps its views for the whole run (a view made per
    # position sample costs about 3 % of a step).
    pa, sa = p[0], s[0]
    for i in range(x_ref.shape[1]):
        t = i * period
        for a in range(n_axes):
            if n_axes > 1:
                pa, sa = p[a], s[a]
            position = outputs[a, OUT_POSITION]
            setpoint = x_ref[a, i]
            if position_on:
                setpoint = setpoint + at_position[a, i]
            position_loop(pa, sa, t, setpoint, v_ref[a, i], a_ref[a, i], position)
            record[a, i, 0] = t
            record[a, i, 1] = x_ref[a, i]
            record[a, i, 2] = v_ref[a, i]
            record[a, i, 3] = position
            record[a, i, 4] = setpoint - position
            record[a, i, 5] = outputs[a, OUT_ANGLE]
            record[a, i, 6] = outputs[a, OUT_SPEED]
            record[a, i, 7] = sa[SPEED_CMD]
            if abs(setpoint - position) > abort_error:
                return ABORTED, i * ratio, a
            set_real, step, get_real = set_reals[a], steps[a], get_reals[a]
            version, component = versions[a], components[a]
            axis_vr_in = vr_in.ctypes.data + a * vr_in.strides[0]
            axis_inputs = inputs.ctypes.data + a * inputs.strides[0]
            axis_vr_out = vr_out.ctypes.data + a * vr_out.strides[0]
            axis_outputs = outputs.ctypes.data + a * outputs.strides[0]
            current_sum = 0.0
            for j in range(ratio):
                k = i * ratio + j
                if plain:
                    current = speed_loop(pa, sa, k * h, outputs[a, OUT_SPEED])
                    current_sum += current
                else:
                    speed = outputs[a, OUT_SPEED]
                    if noise_on:
                        speed = speed + speed_noise[a, k]
                    command = sa[SPEED_CMD]
                    if speed_on:
                        sa[SPEED_CMD] = command + at_speed[a, k]
                    if recording:
                        speed_record[a, k, 0] = sa[SPEED_CMD]
                    current = speed_loop(pa, sa, k * h, speed)
                    if speed_on:
                        sa[SPEED_CMD] = command
                    current_sum += current
                    if current_on:
                        current = current + at_current[a, k]
                    if recording:
                        speed_record[a, k, 1] = speed
                        speed_record[a, k, 2] = current
                    if torque_on:
                        inputs[a, IN_DISTURBANCE] = load_torque[a, k]
                inputs[a, IN_CURRENT] = current
                status = exchange(
                    version,
                    set_real,
                    step,
                    get_real,
                    component,
                    axis_vr_in,
                    axis_inputs,
                    n_in,
                    axis_vr_out,
                    axis_outputs,
                    n_out,
                    k * h,
                    h,
                    scratch_address,
                )
                if status > FMI2_OK_OR_WARNING:
                    return status, k, a
            record[a, i, 8] = current_sum / ratio
    return 0, -1, -1


def drop_stale_compiled() -> None:
    """Delete numba's cached machine code of these functions when a source they inline or
    compile in (controller.py, the plant contract of plant.py, the statuses of loops/__init__.py)
    is newer.

    numba's cache checks only the source file of the cached function itself; the master inlines
    the controller's functions, so an edited controller would otherwise keep running its old
    form.
    """
    changed = max(Path(module.__file__).stat().st_mtime for module in (controller, plant, loops))
    for function in (master, position_loop, speed_loop, exchange):
        cache_dir = Path(function._cache._cache_path)
        code = function.py_func.__code__
        name = f"{Path(code.co_filename).stem}.{function.py_func.__qualname__}"
        for path in cache_dir.glob(f"{name}-*.nb[ic]"):
            if path.stat().st_mtime < changed:
                path.unlink(missing_ok=True)


drop_stale_compiled()
