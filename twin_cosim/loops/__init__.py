"""The compiled master that steps plant FMUs, and how a process gets it.

:func:`compiled_loops` returns the module whose function ``master``
(:func:`twin_cosim.loops.kernels.master`) steps N axes with the options of a run: the library
compiled ahead for these sources (:mod:`twin_cosim.loops.ahead`, no numba at run time) when it
is built, else compiled just in time by numba (its on-disk cache).
"""

from __future__ import annotations

from types import ModuleType

FMI2_OK_OR_WARNING = 1  # the highest fmi2Status a run goes on after
ABORTED = -2  # the status of a run stopped because its position error left the band

_LOADED: list[ModuleType] = []


def compiled_loops() -> ModuleType:
    """The compiled master of this process: the library built ahead when there is one for these
    sources, else :mod:`twin_cosim.loops.kernels` (numba, just in time); chosen once."""
    if not _LOADED:
        from twin_cosim.loops import ahead

        library = ahead.load()
        if library is None:
            from twin_cosim.loops import kernels

            library = kernels
        _LOADED.append(library)
    return _LOADED[0]


def ready_compiled_loops() -> None:
    """Load the compiled loops now, as the first run would: a process about to run (a pool's
    worker while its parent prepares) calls this ahead. On the just-in-time path this also
    readies numba's compiler target, most of the cost (about 0.3 s) of loading cached code."""
    loops = compiled_loops()
    if loops.__name__ == "twin_cosim.loops.kernels":
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()
