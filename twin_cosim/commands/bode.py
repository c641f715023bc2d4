"""``twin bode``: a loop's frequency response measured on the twin, as a drive measures it."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.console import command_line, warn_plant_mismatch, write_summary
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    number_above,
    out_folder,
    output_options,
    params_option,
    plant_option,
    plant_parameters_option,
    plant_path,
    whole_number,
)

LOOP_CHOICES = ("plant", "current", "speed", "position")  # current: the plant, injected there


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
        "mechanics, eq. (3)), speed or position (required, no default)",
    )
    kind = parser.add_mutually_exclusive_group()
    kind.add_argument(
        "--open", dest="kind", action="store_const", const="open", help="the open loop (default)"
    )
    kind.add_argument(
        "--closed", dest="kind", action="store_const", const="closed", help="the closed loop"
    )
    parser.set_defaults(kind="open")
    parser.add_argument(
        "--nonlinear",
        choices=("on", "off"),
        default="on",
        help="backlash, friction and the other nonlinearities of the plant model",
    )
    _excitation_options(parser)
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    output_options(parser, "output folder (default: out/bode-<scenario>-<loop>-<kind>)")
    data_option(parser)


def _excitation_options(parser: argparse.ArgumentParser) -> None:
    """Amplitude, averaging, operating point, noise, seed."""
    parser.add_argument(
        "--amplitude",
        type=number_above(0.0),
        help="RMS of the multisine: A (plant), rad/s (speed), m (position) (default: what "
        "commands 5 %% of the current limit at high frequency)",
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
        default=0.0,
        help="carriage speed of the operating point, m/s (0: standstill)",
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


def run(args: argparse.Namespace) -> int:
    """Measure, write frf.csv, bode.png (nyquist.png) and bode.json; print the summary."""
    from twin_cosim.frequency.bode import bode, describe, write_bode
    from twin_cosim.frequency.measurement import MeasurementSettings
    from twin_cosim.scenario import load_controller_set, resolve_scenario, with_controller_set
    from twin_cosim.versions import versions

    scenario = resolve_scenario(args.scenario, args.plant_parameters, args.plant)
    if args.params:
        scenario = with_controller_set(scenario, load_controller_set(args.params))
    mismatch = warn_plant_mismatch(scenario, plant_path(args))
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
    out = out_folder(args.out, Path("out") / f"bode-{scenario.name}-{loop}-{args.kind}")
    result = bode(scenario, how, args.nonlinear == "on", plant_path(args))
    command = command_line("bode")
    files = write_bode(result, out, command)
    summary = {
        **result.summary(),
        "command": command,
        "outputs": files,
        "warnings": mismatch,
        "versions": versions(),
    }
    if write_summary(out / "bode.json", summary, args.json):
        print("\n".join(describe(result)))
        print(f"wrote {', '.join(files.values())}, {out / 'bode.json'}")
    return 0
