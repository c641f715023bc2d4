"""``twin step``: the position step and settling test of an axis, as a drive runs it."""

from __future__ import annotations

import argparse

from twin_cosim.commands.console import (
    command_line,
    run_axis_test,
    write_record_csv,
    write_report,
)
from twin_cosim.commands.options import (
    axis_test_options,
    axis_test_parser,
    number_above,
    number_options,
)

NUMBERS = (  # option, type, default, metavar, help
    ("--size", float, 0.1, "MM", "the step of the position setpoint, mm (negative: backwards)"),
    (
        "--band",
        number_above(0.0),
        1.0,
        "UM",
        "the settling band, um: settled once |x - setpoint| stays within it",
    ),
    ("--duration", number_above(0.0), 0.5, "S", "how long the record runs after the step, s"),
)


def add_arguments(subparsers) -> None:
    """The ``step`` command and its options."""
    parser = axis_test_parser(
        subparsers,
        "step",
        "a position step at standstill: rise time, overshoot, settling time to a band, the tail",
        run,
    )
    number_options(parser, NUMBERS)
    axis_test_options(parser, "out/step-<scenario name>")


def run(args: argparse.Namespace) -> int:
    """Run the step, write step.json, step.txt, step.csv and step.png; print the table."""
    from twin_cosim.servo.step import describe, plot_step, step_test

    _, warnings, out, result = run_axis_test(
        args,
        "step",
        lambda plant, scenario: step_test(
            plant, scenario, args.size * 1e-3, args.duration, args.band
        ),
    )
    write_record_csv(out / "step.csv", result.record)
    files = {"record": str(out / "step.csv")}
    if not args.no_plots:
        files["plot"] = str(plot_step(result, out / "step.png", command_line("step")))
    summary = result.summary()
    if summary["current_limited"] and not args.json:
        print(
            f"twin step: note: the current reached its limit ({summary['current_limit_A']:g} A): "
            "the step is too large for a linear response"
        )
    write_report(out, "step", summary, describe(result), files, warnings, args.json)
    return 0
