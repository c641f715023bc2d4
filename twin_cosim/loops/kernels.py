"""The compiled loops: the P-PI cascade stepping plant FMUs through their fmi2 C functions.

Plain Python functions over numbers and arrays, compiled by numba: just in time here (each with
numba's on-disk cache), or ahead of time into one shared library by :mod:`twin_cosim.loops.ahead`
(the same functions, the same machine code semantics, loaded without numba). Callers reach them
through :func:`twin_cosim.loops.compiled_loops`, which picks the shared library when it is built
for these sources.

Every loop returns an fmi2 status (0 when the run finished, :data:`ABORTED` when the position
error left its band) and where it stopped (the speed-loop step, -1 before the first; the lockstep
loop also the axis).
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from twin_cosim import controller
from twin_cosim.loops import ABORTED, FMI2_OK_OR_WARNING, fmi_calls
from twin_cosim.loops.fmi_calls import do_step, real_call
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS

IN_CURRENT, IN_DISTURBANCE = (
    CONTRACT_INPUTS.index(n) for n in ("current_cmd", "disturbance_torque")
)
OUT_ANGLE, OUT_SPEED, OUT_POSITION = (
    CONTRACT_OUTPUTS.index(n) for n in ("motor_angle", "motor_speed", "load_position")
)

# The controller's functions compiled; the loops that call them inline them.
position_loop = numba.njit(cache=True)(controller.position_loop)
speed_loop = numba.njit(cache=True)(controller.speed_loop)


@numba.njit(cache=True)
def read_outputs(get_real, component, vr_out, outputs):  # pragma: no cover - compiled
    """fmi2GetReal of the outputs into ``outputs``; the fmi2 status."""
    return real_call(get_real, component, vr_out.ctypes.data, vr_out.shape[0], outputs.ctypes.data)


@numba.njit(cache=True)
def exchange(
    set_real, step, get_real, component, vr_in, inputs, vr_out, outputs, t, h
):  # pragma: no cover - compiled
    """Set the inputs, doStep(t, h) (s), read the outputs; the first failing fmi2 status, or the
    last one."""
    status = real_call(set_real, component, vr_in.ctypes.data, vr_in.shape[0], inputs.ctypes.data)
    if status > FMI2_OK_OR_WARNING:
        return status
    status = do_step(step, component, t, h, 1)
    if status > FMI2_OK_OR_WARNING:
        return status
    return read_outputs(get_real, component, vr_out, outputs)


@numba.njit(cache=True)
def record_position_sample(record, t, x_ref, v_ref, outputs, speed_cmd):  # pragma: no cover
    """The first eight columns of a record row (``cosim.RECORD_COLUMNS``) at time ``t`` (s)."""
    position = outputs[OUT_POSITION]
    record[0] = t
    record[1] = x_ref
    record[2] = v_ref
    record[3] = position
    record[4] = x_ref - position
    record[5] = outputs[OUT_ANGLE]
    record[6] = outputs[OUT_SPEED]
    record[7] = speed_cmd


@numba.njit(cache=True)
def closed_loop(
    set_real,
    step,
    get_real,
    component,
    vr_in,
    vr_out,
    p,
    s,
    period,
    ratio,
    x_ref,
    v_ref,
    a_ref,
    disturbance,
    command_offset,
    abort_error,
    record,
):  # pragma: no cover - compiled
    """One axis in closed loop (:func:`twin_cosim.cosim.run_fast_path`); fills ``record``."""
    inputs = np.zeros(vr_in.shape[0])
    outputs = np.zeros(vr_out.shape[0])
    h = period / ratio
    status = read_outputs(get_real, component, vr_out, outputs)
    if status > FMI2_OK_OR_WARNING:
        return status, -1
    for i in range(x_ref.shape[0]):
        t = i * period
        position_loop(p, s, t, x_ref[i], v_ref[i], a_ref[i], outputs[OUT_POSITION])
        record_position_sample(record[i], t, x_ref[i], v_ref[i], outputs, s[0])
        if abs(record[i, 4]) > abort_error:
            return ABORTED, i * ratio
        current_sum = 0.0
        inputs[IN_DISTURBANCE] = disturbance[i]  # both held over the position period
        offset = command_offset[i]
        for j in range(ratio):
            k = i * ratio + j
            current = speed_loop(p, s, k * h, outputs[OUT_SPEED])
            inputs[IN_CURRENT] = current + offset
            current_sum += current
            status = exchange(
                set_real, step, get_real, component, vr_in, inputs, vr_out, outputs, k * h, h
            )
            if status > FMI2_OK_OR_WARNING:
                return status, k
        record[i, 8] = current_sum / ratio
    return 0, -1


@numba.njit(cache=True)
def lockstep_loop(
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
    abort_error,
    record,
):  # pragma: no cover - compiled
    """Several axes in lockstep (:func:`twin_cosim.contour.lockstep.run_axes_fast`); one row of
    the address, instance, reference and state arrays per axis; fills ``record[axis]``."""
    n_axes = components.shape[0]
    inputs = np.zeros((n_axes, vr_in.shape[1]))
    outputs = np.zeros((n_axes, vr_out.shape[1]))
    current_sum = np.zeros(n_axes)
    h = period / ratio
    for a in range(n_axes):
        status = read_outputs(get_reals[a], components[a], vr_out[a], outputs[a])
        if status > FMI2_OK_OR_WARNING:
            return status, -1, a
    for i in range(x_ref.shape[1]):
        t = i * period
        for a in range(n_axes):
            position_loop(
                p[a], s[a], t, x_ref[a, i], v_ref[a, i], a_ref[a, i], outputs[a, OUT_POSITION]
            )
            record_position_sample(record[a, i], t, x_ref[a, i], v_ref[a, i], outputs[a], s[a, 0])
            if abs(record[a, i, 4]) > abort_error:
                return ABORTED, i * ratio, a
            current_sum[a] = 0.0
        for j in range(ratio):
            k = i * ratio + j
            for a in range(n_axes):
                current = speed_loop(p[a], s[a], k * h, outputs[a, OUT_SPEED])
                inputs[a, IN_CURRENT] = current
                current_sum[a] += current
                status = exchange(
                    set_reals[a],
                    steps[a],
                    get_reals[a],
                    components[a],
                    vr_in[a],
                    inputs[a],
                    vr_out[a],
                    outputs[a],
                    k * h,
                    h,
                )
                if status > FMI2_OK_OR_WARNING:
                    return status, k, a
        for a in range(n_axes):
            record[a, i, 8] = current_sum[a] / ratio
    return 0, -1, -1


@numba.njit(cache=True)
def measurement_loop(
    set_real,
    step,
    get_real,
    component,
    vr_in,
    vr_out,
    p,
    s,
    period,
    ratio,
    x_ref,
    v_ref,
    a_ref,
    at_current,
    at_speed,
    at_position,
    speed_noise,
    speeds,
    positions,
):  # pragma: no cover - compiled
    """One axis with signals injected into its loops
    (:func:`twin_cosim.frequency.measurement.measure_response`); fills ``speeds`` (speed setpoint
    with injection, measured speed, current per speed-loop sample) and ``positions`` (position
    error, deviation of the reading per position sample)."""
    inputs = np.zeros(vr_in.shape[0])
    outputs = np.zeros(vr_out.shape[0])
    h = period / ratio
    status = read_outputs(get_real, component, vr_out, outputs)
    if status > FMI2_OK_OR_WARNING:
        return status, -1
    for i in range(x_ref.shape[0]):
        x = outputs[OUT_POSITION]
        setpoint = x_ref[i] + at_position[i]
        position_loop(p, s, i * period, setpoint, v_ref[i], a_ref[i], x)
        positions[i, 0] = setpoint - x
        positions[i, 1] = x - x_ref[i]
        for j in range(ratio):
            k = i * ratio + j
            w = outputs[OUT_SPEED] + speed_noise[k]
            command = s[controller.SPEED_CMD]
            s[controller.SPEED_CMD] = command + at_speed[k]
            speeds[k, 0] = s[controller.SPEED_CMD]
            current = speed_loop(p, s, k * h, w) + at_current[k]
            s[controller.SPEED_CMD] = command
            speeds[k, 1] = w
            speeds[k, 2] = current
            inputs[IN_CURRENT] = current
            status = exchange(
                set_real, step, get_real, component, vr_in, inputs, vr_out, outputs, k * h, h
            )
            if status > FMI2_OK_OR_WARNING:
                return status, k
    return 0, -1


LOOPS = (closed_loop, lockstep_loop, measurement_loop)
HELPERS = (position_loop, speed_loop, read_outputs, exchange, record_position_sample)


def drop_stale_compiled() -> None:
    """Delete numba's cached machine code of these functions when a source they inline
    (controller.py, fmi_calls.py) is newer.

    numba's cache checks only the source file of the cached function itself; a loop inlines the
    controller's functions, so an edited controller would otherwise keep running its old form.
    """
    changed = max(Path(module.__file__).stat().st_mtime for module in (controller, fmi_calls))
    for function in LOOPS + HELPERS:
        cache_dir = Path(function._cache._cache_path)
        code = function.py_func.__code__
        name = f"{Path(code.co_filename).stem}.{function.py_func.__qualname__}"
        for path in cache_dir.glob(f"{name}-*.nb[ic]"):
            if path.stat().st_mtime < changed:
                path.unlink(missing_ok=True)


drop_stale_compiled()
