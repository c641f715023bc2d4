"""``twin bode``: a loop's frequency response measured on the twin, as a drive measures it."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.console import command_line, scenario_of, write_report
from twin_cosim.commands.options import (
    axis_test_options,
    command_parser,
    fraction,
    number_above,
    out_folder,
    plant_path,
    whole_number,
)

LOOP_CHOICES = ("plant", "current", "speed", "position", "disturbance")  # current: the plant


def add_arguments(subparsers) -> None:
    """The ``bode`` command and its options."""
    parser = command_parser(
        subparsers, "bode", "measure a loop's frequency response in closed loop, with margins", run
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--loop",
        required=True,
        choices=LOOP_CHOICES,
        help="plant (or current: the excitation at the current command, the response the "
        "mechanics, eq. (3)), speed, position, or disturbance (a torque at the load, the "
        "dynamic stiffness in N/um) (required, no default)",
    )
    kind = parser.add_mutually_exclusive_group()
    kind.add_argument(
        "--open",
        dest="kind",
        action="store_const",
        const="open",
        help="the open loop L (default; the disturbance response is the closed cascade's)",
    )
    kind.add_argument(
        "--closed",
        dest="kind",
        action="store_const",
        const="closed",
        help="the closed loop T = L / (1 + L) (default: the open loop)",
    )
    kind.add_argument(
        "--sensitivity",
        dest="kind",
        action="store_const",
        const="sensitivity",
        help="the sensitivity S = 1 / (1 + L): the loop's error over its setpoint (default: "
        "the open loop)",
    )
    parser.set_defaults(kind=None)
    parser.add_argument(
        "--nonlinear",
        choices=("on", "off"),
        default="on",
        help="backlash, friction and the other nonlinearities of the plant model",
    )
    _excitation_options(parser)
    axis_test_options(parser, "out/bode-<scenario>-<loop>-<kind>")


def _excitation_options(parser: argparse.ArgumentParser) -> None:
    """Amplitude, averaging, operating point, noise, seed."""
    parser.add_argument(
        "--amplitude",
        type=number_above(0.0),
        help="RMS of the multisine: A (plant), rad/s (speed), m (position), N.m (disturbance) "
        "(default: what commands 2 %% of the current limit at high frequency; a disturbance of "
        "20 %% of the drive's friction torque)",
    )
    parser.add_argument(
        "--averages",
        type=whole_number(2),
        default=8,
        help="multisine realisations averaged",
    )
    parser.add_argument(
        "--speed",
        type=float,
        help="carriage speed of the operating point, m/s (0: standstill) (default: 20 rad/s at "
        "the motor, 0.0212 m/s on drive2mass: friction slides one way, the backlash stays "
        "closed, the loop responds as the linearised one)",
    )
    parser.add_argument(
        "--low", type=number_above(0.0), default=1.0, help="lowest excited frequency, Hz"
    )
    parser.add_argument(
        "--noise",
        type=number_above(0.0, inclusive=True),
        default=0.0,
        help="white noise on the measured motor speed, rad/s RMS",
    )
    parser.add_argument("--seed", type=whole_number(0), default=0, help="seed of phases and noise")
    parser.add_argument(
        "--coherence-floor",
        type=fraction(0.0, 1.0),
        default=0.9,
        help="a margin or figure read at or above a line of lower coherence is withheld",
    )


def run(args: argparse.Namespace) -> int:
    """Measure, write frf.csv, bode.png (nyquist.png; stiffness.png), bode.txt and bode.json;
    print the summary."""
    from twin_cosim.frequency.bode import bode, describe, write_bode
    from twin_cosim.frequency.measurement import MeasurementSettings

    scenario, mismatch = scenario_of(args)
    loop = "plant" if args.loop == "current" else args.loop
    how = MeasurementSettings(
        loop,
        args.kind,
        amplitude=args.amplitude,
        averages=args.averages,
        speed=args.speed,
        low_hz=args.low,
        speed_noise=args.noise,
        seed=args.seed,
    )
    out = out_folder(args.out, Path("out") / f"bode-{scenario.name}-{loop}-{how.kind}")
    result = bode(scenario, how, args.nonlinear == "on", plant_path(args), args.coherence_floor)
    files = write_bode(result, out, command_line("bode"), plots=not args.no_plots)
    table = "\n".join(describe(result)) + "\n"
    write_report(out, "bode", result.summary(), table, files, mismatch, args.json)
    return 0
