"""``twin watch``: the twin beside the running machine, over OPC UA (docs/runtime.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.options import (
    command_parser,
    data_option,
    no_plots_option,
    number_above,
    out_folder,
    plant_option,
    plant_path,
    whole_number,
)
from twin_cosim.commands.serve import security_options


def add_arguments(subparsers) -> None:
    """The ``watch`` command and its options."""
    parser = command_parser(
        subparsers,
        "watch",
        "the twin beside the running machine: gap and drift, window by window",
        run,
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--endpoint", required=True, metavar="opc.tcp://HOST:PORT", help="the machine (required)"
    )
    parser.add_argument(
        "--out", metavar="DIR", help="log, trend plot and report (default: out/watch-SCENARIO)"
    )
    parser.add_argument(
        "--plant-parameters",
        metavar="FILE",
        help="the twin's baseline, the plant.yaml of twin diagnose (default: calibrate on the "
        "first windows)",
    )
    parser.add_argument(
        "--baseline",
        type=whole_number(3),
        default=8,
        help="windows of the baseline (calibration and the stationary scatter)",
    )
    parser.add_argument(
        "--track",
        default="coulomb_change,backlash_change,torque_ripple,inertia_change",
        metavar="EFFECT,...",
        help="the effects of the plant model's card to track",
    )
    parser.add_argument(
        "--windows", type=whole_number(1), help="stop after this many windows (default: never)"
    )
    parser.add_argument(
        "--arl",
        type=number_above(1.0),
        default=10_000.0,
        help="average run length to a false alarm, windows (all tests together)",
    )
    parser.add_argument(
        "--poll", type=number_above(0.0), default=1.0, help="seconds between polls of Sequence"
    )
    parser.add_argument(
        "--reconnect-timeout",
        type=number_above(0.0),
        default=60.0,
        help="seconds without a connection before giving up",
    )
    parser.add_argument(
        "--dashboard",
        type=whole_number(1),
        metavar="PORT",
        help="live page on 127.0.0.1:PORT (default: none)",
    )
    parser.add_argument("--no-diagnosis", action="store_true", help="no full diagnosis on an alarm")
    security_options(parser, "to connect with")
    parser.add_argument("--quiet", action="store_true", help="no line per window on stdout")
    no_plots_option(parser)
    plant_option(parser)
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Watch; exit 0 without an alarm, 1 with alarms or a link given up, 128 + N on signal N."""
    from twin_cosim.runtime.report import write_report
    from twin_cosim.runtime.security import security_from
    from twin_cosim.runtime.tracker import tracked_parameters
    from twin_cosim.runtime.watch import WatchOptions, watch
    from twin_cosim.scenario import resolve_scenario

    security = security_from(args.security, args.certificate, args.private_key)
    scenario = resolve_scenario(args.scenario, args.plant_parameters, plant_path(args))
    out = out_folder(args.out, Path("out") / f"watch-{scenario.name}")
    fmu = str(scenario.plant_fmu(plant_path(args)))
    tracked = tuple(name.strip() for name in args.track.split(",") if name.strip())
    tracked_parameters(scenario.model_name(plant_path(args)), tracked)  # refused here if unknown
    summary = watch(
        WatchOptions(
            scenario,
            args.endpoint,
            out,
            fmu,
            security,
            baseline=args.baseline,
            calibrate=args.plant_parameters is None,
            tracked=tracked,
            windows=args.windows,
            poll_s=args.poll,
            reconnect_timeout_s=args.reconnect_timeout,
            diagnose=not args.no_diagnosis,
            dashboard_port=args.dashboard,
            design_arl=args.arl,
            quiet=args.quiet,
        )
    )
    files = write_report(summary.log, out, plots=not args.no_plots)
    print(f"wrote {', '.join(str(f) for f in files)}")
    if summary.stopped_by is not None:
        return 128 + summary.stopped_by
    return 1 if summary.alarms or summary.lost else 0
