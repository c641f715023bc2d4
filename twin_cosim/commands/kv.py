"""``twin kv``: the following error against speed and the position-loop gain Kv."""

from __future__ import annotations

import argparse

from twin_cosim.commands.console import command_line, run_axis_test, write_report
from twin_cosim.commands.options import axis_test_options, axis_test_parser, number_above


def add_arguments(subparsers) -> None:
    """The ``kv`` command and its options."""
    parser = axis_test_parser(
        subparsers, "kv", "the following error at constant speeds and the position gain Kv", run
    )
    parser.add_argument(
        "--speeds",
        type=number_above(0.0),
        nargs="+",
        metavar="M_S",
        help="carriage speeds, m/s, each run in both directions (default: 1/8, 1/4, 1/2 and "
        "all of the scenario's fastest reference speed)",
    )
    parser.add_argument(
        "--dwell", type=number_above(0.0), default=0.3, metavar="S", help="time at each speed, s"
    )
    axis_test_options(parser, "out/kv-<scenario name>")


def run(args: argparse.Namespace) -> int:
    """Run the speed levels, write kv.json, kv.txt and kv.png; print the table."""
    from twin_cosim.servo.following import describe, following_test, plot_following

    _, warnings, out, result = run_axis_test(
        args, "kv", lambda plant, scenario: following_test(plant, scenario, args.speeds, args.dwell)
    )
    files: dict[str, str] = {}
    if not args.no_plots:
        files["plot"] = str(plot_following(result, out / "kv.png", command_line("kv")))
    write_report(out, "kv", result.summary(), describe(result), files, warnings, args.json)
    return 0
