"""``twin ssp``: export a machine's plant as an SSP package for other FMI masters."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.options import command_parser


def add_arguments(subparsers) -> None:
    """The ``ssp`` command and its options."""
    parser = command_parser(
        subparsers, "ssp", "export a machine's plant (every axis' FMU and parameters) as SSP", run
    )
    parser.add_argument("scenario", help="machine scenario (axes:), file or shipped name")
    parser.add_argument("--out", metavar="FILE.ssp", help="package to write (default: <name>.ssp)")


def run(args: argparse.Namespace) -> int:
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
