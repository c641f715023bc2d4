"""The FMU and its system: ``twin build`` and ``twin ssp``.

- ``twin build``: build a plant FMU from ``models/<MODEL>``, and the compiled loops ahead;
- ``twin ssp``: export a machine's plant (every axis' FMU and parameters) as an SSP package for
  other FMI masters.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from fmu_build.build import (
    CACHE_ENV,
    DEFAULT_FMI_VERSION,
    DEFAULT_MODEL,
    FMI_VERSIONS,
    available_models,
    build_fmu,
)
from twin_cosim.commands.options import (
    command_parser,
    scenario_parser,
)


def add_build(subparsers) -> None:
    """The ``build`` command and its options."""
    parser = command_parser(
        subparsers,
        "build",
        "build a plant FMU from models/<MODEL> and compile the loops that step it ahead of time",
        run_build,
    )
    parser.add_argument(
        "model", nargs="?", default=DEFAULT_MODEL, help=f"one of {available_models()}"
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        help=f"output folder (default: the per-user cache, ${CACHE_ENV} or "
        "$XDG_CACHE_HOME/twin-cosim, one folder per source version)",
    )
    parser.add_argument(
        "--fmi",
        type=int,
        choices=FMI_VERSIONS,
        default=DEFAULT_FMI_VERSION,
        help="FMI version of the co-simulation FMU: 2 (<MODEL>.fmu) or 3 (<MODEL>-fmi3.fmu)",
    )
    parser.add_argument("--force", action="store_true", help="rebuild even if up to date")


def run_build(args: argparse.Namespace) -> int:
    """Build (or find up to date) the FMU and the compiled loops (in the per-user cache); print
    their paths. Loops that cannot be compiled ahead (no Python headers, say) are a warning:
    they compile just in time, with the same results."""
    from twin_cosim.loops import ahead

    out_dir = Path(args.out) if args.out else None
    print(build_fmu(args.model, out_dir, force=args.force, fmi_version=args.fmi))
    try:
        print(ahead.build(force=args.force))
    except ahead.LoopBuildError as error:
        print(
            f"twin build: warning: {error}; the loops will compile just in time (numba), "
            "with the same results and a slower start",
            file=sys.stderr,
        )
    return 0


def add_ssp(subparsers) -> None:
    """The ``ssp`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "ssp",
        "export a machine's plant (every axis' FMU and parameters) as SSP",
        run_ssp,
        "machine scenario (axes:), file or shipped name",
    )
    parser.add_argument("--out", metavar="FILE.ssp", help="package to write (default: <name>.ssp)")


def run_ssp(args: argparse.Namespace) -> int:
    """Write the package and say where."""
    from twin_cosim.contour.ssp import export_ssp
    from twin_cosim.scenario import load_machine

    machine = load_machine(args.scenario)
    out = Path(args.out) if args.out else Path(f"{machine.name}.ssp")
    if out.is_dir():
        raise ValueError(f"--out {out}: is a folder; give a .ssp file")
    export_ssp(machine, out)
    print(f"wrote {out}: axes {', '.join(machine.axis_names)} (SystemStructure.ssd, resources/)")
    return 0
