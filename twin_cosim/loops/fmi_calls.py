"""Calls of a plant's fmi2 C functions by address, from compiled code.

The compiled loops take the addresses of ``fmi2SetReal``, ``fmi2DoStep`` and ``fmi2GetReal`` and
the instance handle as plain integers, so that their signatures hold only numbers and arrays: the
same functions compile just in time (numba) or ahead of time into a shared library that runs
without numba (:mod:`twin_cosim.loops.ahead`). Each call returns the fmi2Status as an integer;
the caller checks it.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.extending import intrinsic

_STATUS = ir.IntType(32)  # fmi2Status, an enum
_POINTER = ir.IntType(8).as_pointer()
_REAL_CALL = ir.FunctionType(_STATUS, [_POINTER, _POINTER, ir.IntType(64), _POINTER])
_DO_STEP = ir.FunctionType(_STATUS, [_POINTER, ir.DoubleType(), ir.DoubleType(), _STATUS])


@intrinsic
def real_call(typingctx, address, component, references, count, values):  # type: ignore[no-untyped-def]
    """``fmi2SetReal`` or ``fmi2GetReal`` at ``address``: (instance, value references (uint32
    pointer), count, values (float64 pointer)) -> fmi2Status; every argument an integer."""
    signature = types.int64(types.intp, types.intp, types.intp, types.intp, types.intp)

    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        function = builder.inttoptr(args[0], _REAL_CALL.as_pointer())
        component_, references_, count_, values_ = args[1:]
        status = builder.call(
            function,
            [
                builder.inttoptr(component_, _POINTER),
                builder.inttoptr(references_, _POINTER),
                count_,
                builder.inttoptr(values_, _POINTER),
            ],
        )
        return builder.sext(status, ir.IntType(64))

    return signature, codegen


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
