"""``twin simulate MACHINE --program PART.nc``: a part program on a machine of several axes.

The machine branch of :mod:`twin_cosim.commands.simulate`: it writes ``contour.csv`` (the
contour record), ``<axis>.csv`` (each axis' record), ``contour.png`` and ``summary.json``
(``contour_error_max_um``, ``contour_error_rms_um`` and each axis' metrics under ``axes``).
Exit status 1 when an axis' error left the band of ``optimize.abort_error_um`` (the loop
diverged), as for one axis.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from twin_cosim.commands.console import write_json
from twin_cosim.commands.options import out_folder

_SINGLE_AXIS_OPTIONS = ("plant", "plant_parameters", "machine")


def run_program_command(args: argparse.Namespace) -> int:
    """Run the program, write the records, plot and summary; print the summary."""
    from twin_cosim.contour.contour_plot import plot_contour
    from twin_cosim.contour.gcode import read_program
    from twin_cosim.contour.machine_run import (
        MachinePlants,
        axis_metrics,
        contour_metrics,
        run_program,
    )
    from twin_cosim.contour.tuning import contour_settings
    from twin_cosim.scenario import load_axes_parameters, load_machine
    from twin_cosim.versions import versions

    for option in _SINGLE_AXIS_OPTIONS:
        if getattr(args, option, None):
            raise ValueError(
                f"--{option.replace('_', '-')}: for a single-axis scenario; a machine's axes "
                "name their plants and plant.yaml in the scenario (axes.<axis>.plant)"
            )
    machine = load_machine(args.scenario)
    if args.params:
        machine = machine.with_tuned(load_axes_parameters(args.params, machine.axis_names))
    source = Path(args.program) if args.program else machine.program
    if source is None:
        raise ValueError(f"{machine.source}: no program: give --program PART.nc")
    program = read_program(source, machine.axis_names)
    out = out_folder(args.out, Path("out") / machine.name)
    out.mkdir(parents=True, exist_ok=True)
    with MachinePlants(machine) as plants:
        start = time.perf_counter()
        record, _ = run_program(machine, program, plants, not args.reference_path)
        wall = time.perf_counter() - start
    band_um = contour_settings(machine).config.abort_error_um
    warnings = [
        f"axis {name}: the loop diverged: |error| reached {peak:.4g} um, beyond the band of "
        f"{band_um:g} um (optimize.abort_error_um)"
        for name, frame in record.axes.items()
        if not (peak := float(abs(frame["error"]).max()) * 1e6) <= band_um
    ]
    command = "twin simulate " + " ".join(shlex.quote(a) for a in sys.argv[2:])
    record.contour.to_csv(out / "contour.csv", index=False)
    for name, frame in record.axes.items():
        frame.to_csv(out / f"{name}.csv", index=False)
    plot_contour(record, f"{machine.name}: {source.name}", command, out / "contour.png")
    summary: dict[str, Any] = {
        "scenario": str(machine.source),
        "program": str(source),
        **contour_metrics(record),
        "axes": axis_metrics(record),
        "params": {a.name: a.tuned.as_dict() for a in machine.axes},
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "wall_s": wall,
        "outputs": {"contour": str(out / "contour.csv"), "plot": str(out / "contour.png")},
        "warnings": warnings,
        "versions": versions(),
    }
    write_json(out / "summary.json", summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"{machine.name} {source.name}: contour error max "
            f"{summary['contour_error_max_um']:.2f} um, RMS {summary['contour_error_rms_um']:.2f}"
            f" um; "
            + ", ".join(f"{n} E_pk {m['E_pk_um']:.2f} um" for n, m in summary["axes"].items())
            + f" ({wall:.2f} s wall)"
        )
        print(f"wrote {out}/contour.csv, contour.png, summary.json")
    for warning in warnings:
        print(f"twin simulate: warning: {warning}", file=sys.stderr)
    return 1 if warnings else 0
