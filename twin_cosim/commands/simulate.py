"""``twin simulate``: run a scenario in closed loop, judge the run, write its record and plot; a
part program on a machine of several axes (``twin simulate MACHINE --program PART.nc``)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim.commands.console import (
    command_line,
    warn_plant_mismatch,
    write_record_csv,
    write_summary,
)
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    no_plots_option,
    out_folder,
    output_options,
    params_option,
    plant_option,
    plant_parameters_option,
    plant_path,
)

_SINGLE_AXIS_OPTIONS = ("plant", "plant_parameters", "machine")  # not for a machine's program

if TYPE_CHECKING:
    from twin_cosim.controller import TunedParameters
    from twin_cosim.metrics import Metrics
    from twin_cosim.painter import Painter
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario


def add_arguments(subparsers) -> None:
    """The ``simulate`` command and its options."""
    parser = command_parser(subparsers, "simulate", "run a scenario in closed loop", run)
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    parser.add_argument(
        "--machine",
        metavar="RUN_OR_PLANT",
        help="judge on a machine: a measured run (CSV/.mat) made with these gains, or a virtual "
        "machine (a scenario or plant.yaml whose plant stands for the machine, e.g. the "
        "RUN.machine.yaml or RUN.truth.json twin synth writes) (default: none)",
    )
    parser.add_argument(
        "--program",
        metavar="PART.nc",
        help="part program (G-code subset, docs/contouring.md) for a machine scenario (axes:) "
        "(default: the scenario's program)",
    )
    output_options(parser, "output folder (default: out/<scenario name>)")
    parser.add_argument(
        "--reference-path",
        action="store_true",
        help="step through fmpy in plain Python instead of the compiled loop",
    )
    no_plots_option(parser)
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Simulate, write record.csv and summary.json, print the result, then plot run.png; 1 when
    the loop diverged or oscillates (a limit cycle, a chattering current). A machine scenario
    (axes:) or a part program runs on every axis."""
    from twin_cosim.scenario import is_machine_scenario

    if args.program or is_machine_scenario(args.scenario):
        return _run_program(args)
    from twin_cosim.painter import Painter

    painter = None if args.no_plots else Painter.start()  # imports matplotlib meanwhile
    try:
        return _run_scenario(args, painter)
    finally:
        if painter is not None:
            painter.close()


def _run_scenario(args: argparse.Namespace, painter: Painter | None) -> int:
    """:func:`run` of a single-axis scenario; ``painter`` draws run.png (None: no figure)."""
    from twin_cosim.metrics import compute_metrics
    from twin_cosim.run_checks import loop_warnings
    from twin_cosim.scenario import load_controller_set, resolve_scenario, with_controller_set

    scenario = resolve_scenario(args.scenario, args.plant_parameters, args.plant)
    if args.params:
        scenario = with_controller_set(scenario, load_controller_set(args.params))
    tuned = scenario.tuned
    mismatch = warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / scenario.name)
    out.mkdir(parents=True, exist_ok=True)
    record, ran = _simulate(scenario, tuned, plant_path(args), not args.reference_path)
    metrics = compute_metrics(record, scenario.metrics_window)
    unusable, loop = loop_warnings(record, scenario)
    summary = _summary(args, scenario, tuned, record, metrics, ran, mismatch + loop, out)
    write_record_csv(out / "record.csv", record)
    if write_summary(out / "summary.json", summary, args.json):
        _print_text(scenario.name, metrics, summary, args.machine)
    for warning in loop:  # the plant mismatch was said as it was found
        print(f"twin simulate: warning: {warning}", file=sys.stderr)
    drawn = True
    if painter is not None:
        from twin_cosim.paper import set_name

        title = f"{scenario.name}: {args.params or set_name(scenario.tuned)}"
        sys.stdout.flush()  # the results show while the figure is drawn
        drawn = painter.draw("twin_cosim.plots:plot_run", record, metrics, title, out / "run.png")
    if not args.json:
        plot = "run.png, " if painter is not None and drawn else ""
        print(f"wrote {out}/record.csv, {plot}summary.json")
    return 1 if unusable or not drawn else 0


def _simulate(
    scenario: Scenario, tuned: TunedParameters, fmu: Path | None, fast: bool
) -> tuple[RunRecord, dict[str, Any]]:
    """The run's record, and the FMU it ran on (``fmu``, else the scenario's) and its wall time.

    Returns
    -------
    tuple
        The record, and ``fmu`` (the FMU's path) and ``wall_s`` (the run's wall time, s).
    """
    from twin_cosim.cosim import run_scenario
    from twin_cosim.plant import Plant

    with Plant(scenario.plant_fmu(fmu)) as plant:
        start = time.perf_counter()
        record = run_scenario(plant, scenario, tuned, fast=fast)
        wall = time.perf_counter() - start
        return record, {"fmu": str(plant.fmu_path), "wall_s": wall}


def _summary(
    args: argparse.Namespace,
    scenario: Scenario,
    tuned: TunedParameters,
    record: RunRecord,
    metrics: Metrics,
    ran: dict[str, Any],
    warnings: list[str],
    out: Path,
) -> dict[str, Any]:
    """summary.json: inputs, metrics, the comparisons with a measured run and a machine.

    ``ran`` is what :func:`_simulate` tells of the run (FMU, wall time in s).
    """
    from twin_cosim.versions import versions

    return {
        "scenario": str(scenario.source),
        "fmu": ran["fmu"],
        "plant_parameters_file": args.plant_parameters,
        "params": tuned.as_dict(),
        "metrics": metrics.as_dict(),
        "validation": _validation(scenario, record),
        "machine": _on_machine(scenario, tuned, args.machine, metrics, args.plant_parameters),
        "metrics_window_s": list(scenario.metrics_window),
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "wall_s": ran["wall_s"],
        "outputs": {
            "record": str(out / "record.csv"),
            "plot": None if args.no_plots else str(out / "run.png"),
        },
        "warnings": warnings,
        "versions": versions(),
    }


def _validation(scenario: Scenario, record: RunRecord) -> dict[str, Any] | None:
    """The run against the scenario's measured run (gaps in um and %), None without one."""
    if scenario.measured is None:
        return None
    from twin_cosim.measured import read_measured
    from twin_cosim.metrics import compare_with_measured

    run = read_measured(scenario.measured)
    return {
        "measured": str(scenario.measured),
        **compare_with_measured(record, run.t, run.x, run.current),
    }


def _on_machine(
    scenario: Scenario,
    tuned: TunedParameters,
    machine: str | None,
    metrics: Metrics,
    plant_file: str | None,
) -> dict[str, Any] | None:
    """The twin's prediction against ``--machine`` (a measured run or a virtual machine), with
    its interval over the plant file's intervals when it has them."""
    if not machine:
        return None
    from twin_cosim.machine import machine_metrics, plant_samples, prediction, sample_metrics

    judged, kind = machine_metrics(scenario, tuned, machine)
    spread = sample_metrics(scenario, tuned, plant_samples(scenario, plant_file))
    return {"source": machine, "kind": kind, **prediction(metrics, judged, spread)}


def _print_text(name: str, metrics: Metrics, summary: dict[str, Any], machine: str | None) -> None:
    """The summary for a reader: metrics, the measured-run gaps, the machine's verdict."""
    m = metrics
    print(
        f"{name}: E_pk {m.E_pk_um:.2f} um, ITAE {m.ITAE:.2f} um.s^2, IAU {m.IAU:.3f} A.s, "
        f"RMS {m.rms_um:.2f} um ({summary['wall_s']:.2f} s wall)"
    )
    v = summary["validation"]
    if v:
        print(
            f"against {v['measured']}: position gap RMS {v['position_rms_gap_um']:.3f} um "
            f"(max {v['position_max_gap_um']:.2f} um, relative "
            f"{v['position_relative_error_pct']:.4f} %), command/force relative error "
            f"{v['current_relative_error_pct']:.3f} %"
        )
    on_machine = summary["machine"]
    if on_machine:
        from twin_cosim.machine import JUDGED, describe

        print(describe(machine, on_machine["kind"], {k: on_machine[k] for k in JUDGED}))


def _run_program(args: argparse.Namespace) -> int:
    """:func:`run` of a machine scenario or a part program: run the program, write the records
    (``contour.csv``, the contour record; ``<axis>.csv``, each axis' record) and ``summary.json``
    (``contour_error_max_um``, ``contour_error_rms_um`` and each axis' metrics under ``axes``),
    print the summary, then plot ``contour.png`` (unless ``--no-plots``). Exit status 1 when an
    axis' error left the band of ``optimize.abort_error_um`` (the loop diverged), as for one
    axis."""
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
        for name, axis in record.axes.items()
        if not (peak := float(abs(axis["error"]).max()) * 1e6) <= band_um
    ]
    write_record_csv(out / "contour.csv", record.contour)
    for name, axis in record.axes.items():
        write_record_csv(out / f"{name}.csv", axis)
    summary: dict[str, Any] = {
        "scenario": str(machine.source),
        "program": str(source),
        **contour_metrics(record),
        "axes": axis_metrics(record),
        "params": {a.name: a.tuned.as_dict() for a in machine.axes},
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "wall_s": wall,
        "outputs": {"contour": str(out / "contour.csv")}
        | ({} if args.no_plots else {"plot": str(out / "contour.png")}),
        "warnings": warnings,
        "versions": versions(),
    }
    if write_summary(out / "summary.json", summary, args.json):
        print(
            f"{machine.name} {source.name}: contour error max "
            f"{summary['contour_error_max_um']:.2f} um, RMS {summary['contour_error_rms_um']:.2f}"
            f" um; "
            + ", ".join(f"{n} E_pk {m['E_pk_um']:.2f} um" for n, m in summary["axes"].items())
            + f" ({wall:.2f} s wall)"
        )
        plot = "" if args.no_plots else ", contour.png"
        print(f"wrote {out}/contour.csv{plot}, summary.json")
    for warning in warnings:
        print(f"twin simulate: warning: {warning}", file=sys.stderr)
    if not args.no_plots:
        from twin_cosim.contour.machine_run import plot_contour  # matplotlib: only to draw

        title = f"{machine.name}: {source.name}"
        plot_contour(record, title, command_line("simulate"), out / "contour.png")
    return 1 if warnings else 0
