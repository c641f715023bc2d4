"""The ``twin`` command line: build, simulate, circle, optimize, compare, synth, diagnose, table3,
ssp, bode, calibrate, autotune, step, kv, friction, serve, watch.

Each command is a pair of functions in a module of :mod:`twin_cosim.commands` (its arguments,
``add_<command>``, and ``run_<command>``), the commands of one concept in one module. Only the
standard library and the light registries are imported at start, so that ``twin --help`` answers
at once; each command imports what it needs (numpy, pandas, fmpy, numba, matplotlib) when it
runs.
"""

from __future__ import annotations

import argparse
import atexit
import os
import signal
import sys

from twin_cosim.commands import (
    axis_tests,
    circle,
    fmu,
    frequency,
    gap,
    optimize,
    paper_tables,
    runtime,
    simulate,
)
from twin_cosim.commands.options import HelpFormatter
from twin_cosim.environment import DATA_ENV

COMMANDS = (
    fmu.add_build,
    simulate.add_simulate,
    circle.add_circle,
    optimize.add_optimize,
    paper_tables.add_compare,
    gap.add_synth,
    gap.add_diagnose,
    paper_tables.add_table3,
    fmu.add_ssp,
    frequency.add_bode,
    frequency.add_calibrate,
    frequency.add_autotune,
    axis_tests.add_step,
    axis_tests.add_kv,
    axis_tests.add_friction,
    runtime.add_serve,
    runtime.add_watch,
)  # each adds one command, in the help's order


def user_errors() -> tuple[type[Exception], ...]:
    """The exceptions that are the user's mistakes: a message and exit status 2."""
    from fmu_build.build import BuildError
    from fmu_build.variable_table import VariableTableError
    from twin_cosim.plant import PlantError
    from twin_cosim.reference import ReferenceError
    from twin_cosim.scenario import ScenarioError

    return (
        BuildError,
        VariableTableError,
        PlantError,
        ScenarioError,
        ReferenceError,
        ValueError,
        OSError,  # a file or folder that cannot be read or written; the message names it
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``twin``: one subcommand per function of :data:`COMMANDS`."""
    parser = argparse.ArgumentParser(
        prog="twin", description="Digital twin of a CNC feed axis", formatter_class=HelpFormatter
    )
    subparsers = parser.add_subparsers(dest="command", required=True)
    for add_command in COMMANDS:
        add_command(subparsers)
    return parser


def run() -> None:
    """Entry point of the ``twin`` console script and of ``python -m twin_cosim``: :func:`main`,
    then the end of the process.

    Once every file is closed, every pool shut down and every ``atexit`` handler run, the process
    ends at once instead of tearing the interpreter down (a third of a second once numba, pandas
    and matplotlib are loaded). A status that :func:`main` did not return (an exception, or
    argparse's exit) ends the usual way.
    """
    global _status
    atexit.register(_end_at_once)  # registered first: runs after every other handler
    _status = main()
    for signum in (signal.SIGINT, signal.SIGTERM):  # the status is known: the process ends
        signal.signal(signum, signal.SIG_IGN)
    sys.exit(_status)


_status: int | None = None  # the status main returned, once it has


def _end_at_once() -> None:
    if _status is None:
        return
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (twin ... | head) or stream
            pass
    os._exit(_status)


def main(argv: list[str] | None = None) -> int:
    """The ``twin`` command line (:func:`run` is its entry point).

    Exit status: 0 done; 1 done, but the result needs attention (``simulate``: the loop
    diverged or oscillates); 2 a user error (bad file, key or option), with a message naming
    it; 128 + N ended by signal N (130 Ctrl-C, 143 SIGTERM), after a clean shutdown.
    """
    args = build_parser().parse_args(argv)
    if getattr(args, "data", None):
        os.environ[DATA_ENV] = args.data  # also seen by worker processes
    from twin_cosim.workers import Terminated, command_temp_folder, stop_handlers

    with stop_handlers():  # a second signal never interrupts the shutdown the first began
        try:
            with command_temp_folder():
                return args.handler(args)
        except KeyboardInterrupt as exc:  # first: an interrupted import must not be retried
            hint = getattr(exc, "hint", "")
            print(f"twin {args.command}: interrupted{hint}", file=sys.stderr)
            return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)
        except user_errors() as exc:
            print(f"twin {args.command}: error: {exc}", file=sys.stderr)
            return 2


if __name__ == "__main__":
    run()
