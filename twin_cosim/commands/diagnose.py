"""``twin diagnose``: where the twin is wrong, why, and by how much; the calibrated plant file."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim.commands.console import warn_plant_mismatch
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    fraction,
    no_plots_option,
    out_folder,
    output_options,
    plant_option,
    plant_path,
    whole_number,
)

if TYPE_CHECKING:
    from twin_cosim.gap.diagnosis import Diagnosis
    from twin_cosim.workers import ProcessPool, SerialPool


def add_arguments(subparsers) -> None:
    """The ``diagnose`` command and its options."""
    parser = command_parser(
        subparsers, "diagnose", "where the twin is wrong, why, and by how much", run
    )
    parser.add_argument("scenario", help="scenario YAML file (or shipped name) the runs followed")
    parser.add_argument(
        "--measured",
        action="append",
        required=True,
        help="measured run, CSV or EMPS .mat (repeatable; required, no default)",
    )
    parser.add_argument(
        "--holdout", action="append", help="held-out run(s) (default: a time split)"
    )
    parser.add_argument(
        "--split",
        type=fraction(0.1, 0.9),
        help="training fraction of the time split "
        "(default: the scenario's diagnose.split, else 0.5)",
    )
    parser.add_argument(
        "--max-effects",
        type=whole_number(1),
        help="effects to accept at most (default: the scenario's diagnose.max_effects, else 3)",
    )
    plant_option(parser)
    parser.add_argument(
        "--workers",
        type=whole_number(1),
        help="local processes for the fits (default: all cores)",
    )
    output_options(parser, "report folder (default: out/diagnosis-<scenario name>)")
    parser.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (there is none either with --json when stdout is not a terminal)",
    )
    no_plots_option(parser)
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Diagnose, write the report, plant.yaml and calibrated.yaml, print the verdict, then draw
    the report's figures.

    The replay pool's processes start first, so that they load the co-simulation while this
    process reads the runs and replays the nominal twin.
    """
    from twin_cosim.pool_runs import prepare_replay_worker
    from twin_cosim.workers import make_pool

    with make_pool(None, args.workers, prepare_replay_worker) as pool:
        return _run_on(args, pool)


def _run_on(args: argparse.Namespace, pool: SerialPool | ProcessPool) -> int:
    """The diagnosis, its files and its figures, with ``pool`` running the replays."""
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.gap.report.pages import summary as summary_of
    from twin_cosim.gap.report.pages import write_report
    from twin_cosim.gap.settings import settings_from
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import resolve_scenario
    from twin_cosim.versions import versions

    scenario = resolve_scenario(args.scenario)
    mismatch = warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / f"diagnosis-{scenario.name}")
    measured = [read_measured(path) for path in args.measured]
    holdout = [read_measured(path) for path in args.holdout or []]
    settings = settings_from(scenario, args.split, args.max_effects)
    start = time.perf_counter()
    progress = _ProgressBars(args)
    try:
        result = diagnose(
            scenario, measured, holdout, args.plant, settings, progress=progress, pool=pool
        )
    finally:
        progress.finish()
    wall_s = time.perf_counter() - start
    summary = {
        **summary_of(result),
        "wall_s": wall_s,
        "versions": versions(),
        "warnings": mismatch + result.warnings,
    }
    files = write_report(result, out, summary, _command(args), figures=not args.no_plots)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_text(result)
    if not args.no_plots:
        from twin_cosim.gap.report.figures import write_figures

        write_figures(result, out)
    if not args.json:
        print(
            f"wrote {files['markdown']}, {files['html']}, {files['json']}, {files['plant']}, "
            f"{files['calibrated']}{'' if args.no_plots else ' and figures'} ({wall_s:.1f} s)"
        )
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command that made the diagnosis, as plant.yaml records it."""
    runs = [f"--measured {m}" for m in args.measured]
    runs += [f"--holdout {h}" for h in args.holdout or []]
    return " ".join(["twin diagnose", str(args.scenario), *runs])


class _ProgressBars:
    """tqdm progress bars on stderr, one per ``make(total, label)``; none with ``--quiet``, or
    with ``--json`` when stdout is not a terminal. A bar's total is the most tasks the work may
    take; :meth:`finish` closes each bar at 100 % of what it did."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.enabled = not args.quiet and not (args.json and not sys.stdout.isatty())
        self.bars: list[Any] = []

    def __call__(self, total: int, label: str) -> Callable[[int], None]:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=label, unit="task", disable=not self.enabled, file=sys.stderr)
        self.bars.append(bar)

        def tick(done: int) -> None:
            if bar.n + done > bar.total:
                bar.total = bar.n + done
            bar.update(done)

        return tick

    def finish(self) -> None:
        """Close every bar, its total set to the tasks done (the work ended early)."""
        for bar in self.bars:
            bar.total = bar.n
            bar.close()
        self.bars = []


def _print_text(result: Diagnosis) -> None:
    """The verdict and each accepted effect's held-out gaps, numbers for people."""
    from twin_cosim.gap.report.pages import hypothesis_units
    from twin_cosim.gap.verdict import names, number, parameters

    units = hypothesis_units(result.context.model)
    print(result.verdict)
    for step in result.steps:
        best = step.best
        assert best is not None
        print(
            f"  {names([step.effect])}: held-out position gap "
            f"{number(step.position_rms_um)} -> {number(best.judgement.position_rms_um)} "
            f"um, current {number(step.current_rms)} -> "
            f"{number(best.judgement.current_rms)} A, as fitted in its round: "
            f"{parameters(best.fit.values, units.get(best.name, {}))}"
        )
