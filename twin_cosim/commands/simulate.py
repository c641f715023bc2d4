"""``twin simulate``: run a scenario in closed loop, judge the run, write its record and plot; a
part program on a machine of several axes (``twin simulate MACHINE --program PART.nc``); an
open-loop scenario's replay of a measured run (``twin simulate hsm150 --machine RUN.mat``)."""

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
    column_map,
    columns_option,
    data_option,
    feed_override_option,
    no_plots_option,
    out_folder,
    output_options,
    params_option,
    plant_option,
    plant_parameters_option,
    plant_path,
    scenario_parser,
)

_SINGLE_AXIS_OPTIONS = ("plant", "plant_parameters", "machine")  # not for a machine's program

if TYPE_CHECKING:
    from twin_cosim.controller import TunedParameters
    from twin_cosim.metrics import Metrics
    from twin_cosim.open_loop import OpenLoopComparison
    from twin_cosim.painter import Painter
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario


def add_simulate(subparsers) -> None:
    """The ``simulate`` command and its options."""
    parser = scenario_parser(subparsers, "simulate", "run a scenario in closed loop", run_simulate)
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    parser.add_argument(
        "--machine",
        metavar="RUN_OR_PLANT",
        help="judge on a machine: a measured run (CSV/.mat) made with these gains, or a virtual "
        "machine (a scenario or plant.yaml whose plant stands for the machine, e.g. the "
        "RUN.machine.yaml or RUN.truth.json twin synth writes); for an open-loop scenario "
        "(reference.drive), the measured run whose drive signal the twin replays and whose "
        "speeds it is compared with (default: none; an open-loop scenario's own run)",
    )
    columns_option(parser)
    parser.add_argument(
        "--program",
        metavar="PART.nc",
        help="part program (G-code subset, docs/contouring.md) for a machine scenario (axes:) "
        "(default: the scenario's program)",
    )
    feed_override_option(parser)
    output_options(parser, "output folder (default: out/<scenario name>)")
    parser.add_argument(
        "--reference-path",
        action="store_true",
        help="step through fmpy in plain Python instead of the compiled loop",
    )
    no_plots_option(parser)
    data_option(parser)


def run_simulate(args: argparse.Namespace) -> int:
    """Simulate, write record.csv and summary.json, print the result, then plot run.png; 1 when
    the loop diverged or oscillates (a limit cycle, a chattering current). A machine scenario
    (axes:) or a part program runs on every axis."""
    from twin_cosim.scenario import is_machine_scenario

    if args.program or is_machine_scenario(args.scenario):
        return _run_program(args)
    if args.feed_override != 100.0:
        raise ValueError("--feed-override: for a part program on a machine scenario (axes:)")
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
    if scenario.drive is not None:
        return _run_open_loop(args, scenario, painter)
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
        from twin_cosim.controller_set import set_name

        title = f"{scenario.name}: {args.params or set_name(scenario.tuned)}"
        sys.stdout.flush()  # the results show while the figure is drawn
        drawn = painter.draw("twin_cosim.plots:plot_run", record, metrics, title, out / "run.png")
    if not args.json:
        plot = "run.png, " if painter is not None and drawn else ""
        print(f"wrote {out}/record.csv, {plot}summary.json")
    return 1 if unusable or not drawn else 0


def _run_open_loop(args: argparse.Namespace, scenario: Scenario, painter: Painter | None) -> int:
    """:func:`run` of an open-loop scenario: replay the measured run's drive signal (``--machine``,
    else the scenario's own run), write record.csv with the measured position and speed beside
    the twin's, summary.json with the velocity gap and the steady speeds, and run.png."""
    from twin_cosim.measured import read_measured
    from twin_cosim.open_loop import compare_open_loop, with_measured
    from twin_cosim.scenario import for_measured_run

    mismatch = warn_plant_mismatch(scenario, plant_path(args))
    source = Path(args.machine) if args.machine else scenario.measured
    run = read_measured(source, column_map(args, scenario), open_loop=True)
    scenario = for_measured_run(scenario, run)
    run = scenario.measured_run(run)
    out = out_folder(args.out, Path("out") / scenario.name)
    out.mkdir(parents=True, exist_ok=True)
    record, ran = _simulate(scenario, scenario.tuned, plant_path(args), not args.reference_path)
    comparison = compare_open_loop(run, record, scenario.settings.travel_per_rad)
    summary = {
        "scenario": str(scenario.source),
        "fmu": ran["fmu"],
        "plant_parameters_file": args.plant_parameters,
        "open_loop": comparison.as_dict(),
        **_run_facts(args, ran, out, mismatch),
    }
    write_record_csv(out / "record.csv", with_measured(record, run))
    if write_summary(out / "summary.json", summary, args.json):
        _print_open_loop(scenario.name, comparison, ran["wall_s"])
    drawn = True
    if painter is not None:
        sys.stdout.flush()
        title = f"{scenario.name}: {Path(run.source).name}, driven by {run.drive}"
        drawn = painter.draw(
            "twin_cosim.plots:plot_open_loop",
            with_measured(record, run),
            comparison,
            title,
            out / "run.png",
        )
    if not args.json:
        plot = "run.png, " if painter is not None and drawn else ""
        print(f"wrote {out}/record.csv, {plot}summary.json")
    return 0 if drawn else 1


def _run_facts(
    args: argparse.Namespace, ran: dict[str, Any], out: Path, warnings: list[str]
) -> dict[str, Any]:
    """The entries of a single-axis run's summary.json after its results: the path, the wall
    time (s), the files written, the warnings and the versions."""
    from twin_cosim.versions import versions

    return {
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "wall_s": ran["wall_s"],
        "outputs": {
            "record": str(out / "record.csv"),
            "plot": None if args.no_plots else str(out / "run.png"),
        },
        "warnings": warnings,
        "versions": versions(),
    }


def _print_open_loop(name: str, comparison: OpenLoopComparison, wall_s: float) -> None:
    """An open-loop replay for a reader: the velocity gap and each level's steady speeds."""
    c = comparison
    print(
        f"{name}: {Path(c.run).name} driven by {c.drive}: velocity gap RMS "
        f"{c.speed_rms_gap_rad_s:.3g} rad/s ({c.speed_relative_error_pct:.3g} %), angle gap RMS "
        f"{c.angle_rms_gap_rad:.4g} rad ({wall_s:.2f} s wall)"
    )
    for level in c.levels:
        print(
            f"  {level.start_s:.4g}-{level.end_s:.4g} s at {level.commanded:.4g} "
            f"{c.commanded_unit}: "
            f"steady speed measured {level.measured_rad_s:.4g} rad/s, twin "
            f"{level.twin_rad_s:.4g} rad/s ({level.relative_error_pct:+.1f} %)"
        )


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

    return {
        "scenario": str(scenario.source),
        "fmu": ran["fmu"],
        "plant_parameters_file": args.plant_parameters,
        "params": tuned.as_dict(),
        "metrics": metrics.as_dict(),
        "validation": _validation(scenario, record),
        "machine": _on_machine(scenario, tuned, args, metrics),
        "metrics_window_s": list(scenario.metrics_window),
        **_run_facts(args, ran, out, warnings),
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
    scenario: Scenario, tuned: TunedParameters, args: argparse.Namespace, metrics: Metrics
) -> dict[str, Any] | None:
    """The twin's prediction against ``--machine`` (a measured run, its columns by
    ``--columns``, or a virtual machine), with its interval over the plant file's intervals
    widened by its model error (``--plant-parameters``) when it has them."""
    machine = args.machine
    if not machine:
        return None
    from twin_cosim.machine import (
        machine_metrics,
        model_error_margins,
        plant_samples,
        prediction,
        sample_metrics,
    )

    judged, kind = machine_metrics(scenario, tuned, machine, column_map(args, scenario))
    spread = sample_metrics(scenario, tuned, plant_samples(scenario, args.plant_parameters))
    margins = model_error_margins(scenario, args.plant_parameters)
    return {"source": machine, "kind": kind, **prediction(metrics, judged, spread, margins)}


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
    (``contour_error_max_um``, ``contour_error_rms_um``, the path time, the feeds programmed and
    reached, each axis' metrics under ``axes``, the words ignored), print the summary, then plot
    ``contour.png`` (unless ``--no-plots``). Exit status 1 when an axis' error left the band of
    ``optimize.abort_error_um`` (the loop diverged), as for one axis."""
    from twin_cosim.contour.gcode import read_program
    from twin_cosim.contour.interpolation import feed_warnings
    from twin_cosim.contour.machine_run import (
        MachinePlants,
        axis_metrics,
        contour_metrics,
        plan_on,
        run_machine,
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
    start = time.perf_counter()
    motion = plan_on(machine, program, args.feed_override / 100.0)  # refused before it runs
    planned = time.perf_counter() - start
    out.mkdir(parents=True, exist_ok=True)
    with MachinePlants(machine) as plants:
        start = time.perf_counter()
        record = run_machine(machine, motion, plants, not args.reference_path)
        wall = time.perf_counter() - start
    band_um = contour_settings(machine).config.abort_error_um
    diverged = [
        f"axis {name}: the loop diverged: |error| reached {peak:.4g} um, beyond the band of "
        f"{band_um:g} um (optimize.abort_error_um)"
        for name, axis in record.axes.items()
        if not (peak := float(abs(axis["error"]).max()) * 1e6) <= band_um
    ]
    warnings = feed_warnings(motion) + diverged
    write_record_csv(out / "contour.csv", record.contour)
    for name, axis in record.axes.items():
        write_record_csv(out / f"{name}.csv", axis)
    fed = [f for f in motion.feeds if f.programmed is not None]
    summary: dict[str, Any] = {
        "scenario": str(machine.source),
        "program": str(source),
        **contour_metrics(record),
        "path_time_s": motion.end_time,
        "path_control": machine.path_control.describe(),
        "feed_override_pct": args.feed_override,
        "feed_programmed_mm_min": max((f.programmed * 60e3 for f in fed), default=None),
        "feed_reached_mm_min": max((f.reached * 60e3 for f in fed), default=None),
        "axes": axis_metrics(record),
        "params": {a.name: a.tuned.as_dict() for a in machine.axes},
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "plan_s": planned,
        "wall_s": wall,
        "outputs": {"contour": str(out / "contour.csv")}
        | ({} if args.no_plots else {"plot": str(out / "contour.png")}),
        "ignored": [{"line": w.line, "word": w.word} for w in program.ignored],
        "warnings": warnings,
        "versions": versions(),
    }
    if write_summary(out / "summary.json", summary, args.json):
        print(_program_headline(machine.name, source.name, summary))
        plot = "" if args.no_plots else ", contour.png"
        print(f"wrote {out}/contour.csv{plot}, summary.json")
    if program.ignored:
        print(
            "twin simulate: note: ignored (they do not move the axes): "
            + program.ignored_summary(),
            file=sys.stderr,
        )
    for warning in warnings:
        print(f"twin simulate: warning: {warning}", file=sys.stderr)
    if not args.no_plots:
        from twin_cosim.contour.machine_run import plot_contour  # matplotlib: only to draw

        title = f"{machine.name}: {source.name}"
        plot_contour(record, title, command_line("simulate"), out / "contour.png")
    return 1 if diverged else 0


def _program_headline(machine: str, program: str, summary: dict[str, Any]) -> str:
    """A program run's summary in one line: contour error, path time, feed reached, axes."""
    feed = ""
    if summary["feed_programmed_mm_min"] is not None:
        feed = (
            f", feed reached {summary['feed_reached_mm_min']:.0f} of "
            f"{summary['feed_programmed_mm_min']:.0f} mm/min"
        )
        if summary["feed_override_pct"] != 100.0:
            feed += f" (override {summary['feed_override_pct']:g} %)"
    return (
        f"{machine} {program}: contour error max {summary['contour_error_max_um']:.2f} um, RMS "
        f"{summary['contour_error_rms_um']:.2f} um; path {summary['path_time_s']:.2f} s"
        + feed
        + "; "
        + ", ".join(f"{n} E_pk {m['E_pk_um']:.2f} um" for n, m in summary["axes"].items())
        + f" ({summary['wall_s']:.2f} s wall)"
    )
