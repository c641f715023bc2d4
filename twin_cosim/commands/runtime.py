"""The runtime twin over OPC UA (docs/runtime.md): ``twin serve`` and ``twin watch``.

- ``twin serve``: the virtual machine behind an OPC UA server on 127.0.0.1, publishing one trace
  window (one run of the scenario's reference) after another;
- ``twin watch``: the twin beside the running machine, its log, alarms and diagnoses.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from twin_cosim.commands.gap import EFFECTS_HELP, _error_options, effect_option
from twin_cosim.commands.options import (
    data_option,
    no_plots_option,
    number_above,
    number_options,
    out_folder,
    plant_option,
    plant_parameters_option,
    plant_path,
    quiet_option,
    scenario_parser,
    whole_number,
)

SERVE_NUMBERS = (  # option, type, default, metavar, help
    ("--windows", whole_number(1), None, None, "windows to publish (default: until stopped)"),
    (
        "--speed",
        number_above(0.0),
        1.0,
        None,
        "windows published this many times faster than real time",
    ),
    (
        "--linger",
        number_above(0.0, inclusive=True),
        5.0,
        None,
        "seconds the server stays up after the last window",
    ),
)
WATCH_NUMBERS = (  # option, type, default, metavar, help
    (
        "--baseline",
        whole_number(3),
        8,
        None,
        "windows of the baseline (calibration and the stationary scatter)",
    ),
    (
        "--track",
        str,
        "coulomb_change,backlash_change,torque_ripple,inertia_change",
        "EFFECT,...",
        "the effects of the plant model's card to track",
    ),
    ("--windows", whole_number(1), None, None, "stop after this many windows (default: never)"),
    (
        "--arl",
        number_above(1.0),
        10_000.0,
        None,
        "average run length to a false alarm, windows (all tests together)",
    ),
    ("--poll", number_above(0.0), 1.0, None, "seconds between polls of Sequence"),
    (
        "--reconnect-timeout",
        number_above(0.0),
        60.0,
        None,
        "seconds without a connection before giving up",
    ),
    ("--dashboard", whole_number(1), None, "PORT", "live page on 127.0.0.1:PORT (default: none)"),
)


def add_serve(subparsers) -> None:
    """The ``serve`` command and its options."""
    parser = scenario_parser(
        subparsers, "serve", "the virtual machine behind an OPC UA server on 127.0.0.1", run_serve
    )
    parser.epilog = EFFECTS_HELP
    parser.add_argument("--port", type=whole_number(1), required=True, help="TCP port (required)")
    effect_option(
        parser, "hidden effect of the machine (repeatable; as twin synth) (default: none)"
    )
    parser.add_argument(
        "--drift",
        action="append",
        default=[],
        metavar="NAME:param=RATE",
        help="an effect parameter growing by RATE per window, e.g. "
        "coulomb_change:delta_coulomb=0.003125 (repeatable) (default: none)",
    )
    parser.add_argument(
        "--drift-start", type=whole_number(0), default=0, help="first window with a drift step"
    )
    _error_options(parser)
    number_options(parser, SERVE_NUMBERS)
    parser.add_argument(
        "--no-motor-speed", action="store_true", help="publish no motor_speed array"
    )
    security_options(parser, "the server demands")
    quiet_option(parser, "no line per window")
    plant_option(parser)
    plant_parameters_option(parser)
    data_option(parser)


def security_options(parser: argparse.ArgumentParser, who: str) -> None:
    """``--security``, ``--certificate``, ``--private-key`` (the user from the environment)."""
    from twin_cosim.runtime.opcua import MODES, PASSWORD_ENV, USER_ENV

    parser.add_argument(
        "--security",
        choices=MODES,
        default="None",
        help=f"the Basic256Sha256 mode {who}; a user name and password come from "
        f"${USER_ENV} and ${PASSWORD_ENV} when set",
    )
    parser.add_argument(
        "--certificate",
        metavar="FILE",
        help="application certificate, DER or PEM (default: none; needed with --security)",
    )
    parser.add_argument(
        "--private-key", metavar="FILE", help="its private key, PEM (default: none)"
    )


def run_serve(args: argparse.Namespace) -> int:
    """Serve the virtual machine's windows until done (or stopped)."""
    import asyncio

    from twin_cosim.gap.synth import parse_effect
    from twin_cosim.runtime.opcua import MachineServer, security_from, serve_machine
    from twin_cosim.runtime.virtual_machine import draw_machine, parse_drift
    from twin_cosim.scenario import resolve_scenario

    security = security_from(args.security, args.certificate, args.private_key)
    scenario = resolve_scenario(args.scenario, args.plant_parameters, plant_path(args))
    fmu = str(scenario.plant_fmu(plant_path(args)))
    machine = draw_machine(
        scenario,
        fmu,
        [parse_effect(text) for text in args.effect],
        [parse_drift(text) for text in args.drift],
        args.drift_start,
        args.perturb,
        args.seed,
        args.noise_position,
        args.noise_current,
    )
    server = MachineServer(args.port, security=security, with_motor_speed=not args.no_motor_speed)

    async def serve() -> int:
        try:
            await server.start()
        except OSError as exc:
            raise OSError(f"--port {args.port}: cannot listen on 127.0.0.1 ({exc})") from None
        print(f"serving {scenario.name} at {server.endpoint} ({security.mode})", flush=True)
        try:
            published = await serve_machine(
                server,
                machine.window,
                args.windows,
                args.speed,
                announce=None if args.quiet else lambda text: print(text, flush=True),
            )
            await asyncio.sleep(args.linger)
        finally:
            await server.stop()
        return published

    published = asyncio.run(serve())
    print(f"published {published} windows", file=sys.stderr)
    return 0


def add_watch(subparsers) -> None:
    """The ``watch`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "watch",
        "the twin beside the running machine: gap and drift, window by window",
        run_watch,
    )
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
    number_options(parser, WATCH_NUMBERS)
    parser.add_argument("--no-diagnosis", action="store_true", help="no full diagnosis on an alarm")
    security_options(parser, "to connect with")
    quiet_option(parser, "no line per window on stdout")
    no_plots_option(parser)
    plant_option(parser)
    data_option(parser)


def run_watch(args: argparse.Namespace) -> int:
    """Watch; exit 0 without an alarm, 1 with alarms or a link given up, 128 + N on signal N."""
    from twin_cosim.runtime.opcua import security_from
    from twin_cosim.runtime.tracker import tracked_parameters
    from twin_cosim.runtime.watch import WatchOptions, watch
    from twin_cosim.runtime.watch_log import write_report
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
