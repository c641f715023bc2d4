"""``twin serve``: the virtual machine behind an OPC UA server on 127.0.0.1, publishing one trace
window (one run of the scenario's reference) after another (docs/runtime.md)."""

from __future__ import annotations

import argparse
import sys

from twin_cosim.commands.options import (
    command_parser,
    data_option,
    number_above,
    plant_option,
    plant_parameters_option,
    plant_path,
    whole_number,
)
from twin_cosim.commands.synth import EFFECTS_HELP, _error_options


def add_arguments(subparsers) -> None:
    """The ``serve`` command and its options."""
    parser = command_parser(
        subparsers, "serve", "the virtual machine behind an OPC UA server on 127.0.0.1", run
    )
    parser.epilog = EFFECTS_HELP
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument("--port", type=whole_number(1), required=True, help="TCP port (required)")
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="hidden effect of the machine (repeatable; as twin synth) (default: none)",
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
    parser.add_argument(
        "--windows", type=whole_number(1), help="windows to publish (default: until stopped)"
    )
    parser.add_argument(
        "--speed",
        type=number_above(0.0),
        default=1.0,
        help="windows published this many times faster than real time",
    )
    parser.add_argument(
        "--linger",
        type=number_above(0.0, inclusive=True),
        default=5.0,
        help="seconds the server stays up after the last window",
    )
    parser.add_argument(
        "--no-motor-speed", action="store_true", help="publish no motor_speed array"
    )
    security_options(parser, "the server demands")
    parser.add_argument("--quiet", action="store_true", help="no line per window")
    plant_option(parser)
    plant_parameters_option(parser)
    data_option(parser)


def security_options(parser: argparse.ArgumentParser, who: str) -> None:
    """``--security``, ``--certificate``, ``--private-key`` (the user from the environment)."""
    from twin_cosim.runtime.security import MODES, PASSWORD_ENV, USER_ENV

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


def run(args: argparse.Namespace) -> int:
    """Serve the virtual machine's windows until done (or stopped)."""
    import asyncio

    from twin_cosim.gap.synth import parse_effect
    from twin_cosim.runtime.security import security_from
    from twin_cosim.runtime.server import MachineServer, serve_machine
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
