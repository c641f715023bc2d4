"""The compiled master that steps plant FMUs, and how a process gets it.

:func:`twin_cosim.loops.ahead.compiled_loops` returns the module whose function ``master``
(:func:`twin_cosim.loops.kernels.master`) steps N axes with the options of a run: the library
compiled ahead for these sources (:mod:`twin_cosim.loops.ahead`, no numba at run time) when it
is built, else compiled just in time by numba (its on-disk cache). This module holds the statuses
the master returns.
"""

FMI2_OK_OR_WARNING = 1  # the highest fmi2Status (and fmi3Status) a run goes on after
ABORTED = -2  # the status of a run stopped because its position error left the band
