"""The servo tests of an axis in the time domain, run on the twin as a drive runs them:
``twin step``, ``twin kv`` and ``twin friction``.

- ``twin step``: the position step and settling test;
- ``twin kv``: the following error against speed and the position-loop gain Kv;
- ``twin friction``: the friction curve as drives measure it, fitted, written as plant.yaml.

Each shares the options of a test of an axis (:func:`twin_cosim.commands.options.axis_test_options`)
and its outputs (:func:`twin_cosim.commands.console.write_report`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.console import (
    command_line,
    run_axis_test,
    scenario_of,
    write_record_csv,
    write_report,
)
from twin_cosim.commands.options import (
    axis_test_options,
    number_above,
    number_options,
    out_folder,
    scenario_parser,
    whole_number,
)

STEP_NUMBERS = (  # option, type, default, metavar, help
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


def add_step(subparsers) -> None:
    """The ``step`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "step",
        "a position step at standstill: rise time, overshoot, settling time to a band, the tail",
        run_step,
    )
    number_options(parser, STEP_NUMBERS)
    axis_test_options(parser, "out/step-<scenario name>")


def run_step(args: argparse.Namespace) -> int:
    """Run the step, write step.json, step.txt, step.csv and step.png; print the table."""
    from twin_cosim.servo.position_loop import describe_step, plot_step, step_test

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
    write_report(out, "step", summary, describe_step(result), files, warnings, args.json)
    return 0


def add_kv(subparsers) -> None:
    """The ``kv`` command and its options."""
    parser = scenario_parser(
        subparsers, "kv", "the following error at constant speeds and the position gain Kv", run_kv
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


def run_kv(args: argparse.Namespace) -> int:
    """Run the speed levels, write kv.json, kv.txt and kv.png; print the table."""
    from twin_cosim.servo.position_loop import describe_following, following_test, plot_following

    _, warnings, out, result = run_axis_test(
        args, "kv", lambda plant, scenario: following_test(plant, scenario, args.speeds, args.dwell)
    )
    files: dict[str, str] = {}
    if not args.no_plots:
        files["plot"] = str(plot_following(result, out / "kv.png", command_line("kv")))
    write_report(
        out, "kv", result.summary(), describe_following(result), files, warnings, args.json
    )
    return 0


FRICTION_NUMBERS = (  # option, type, default, metavar, help
    (
        "--max-speed",
        number_above(0.0),
        None,
        "RAD_S",
        "the highest motor speed, rad/s (default: the scenario's fastest reference speed)",
    ),
    ("--min-speed", number_above(0.0), 0.02, "RAD_S", "the lowest motor speed, rad/s"),
    ("--levels", whole_number(3), 24, "N", "speeds per direction, log-spaced"),
    ("--dwell", number_above(0.0), 0.5, "S", "time at each speed, s"),
)


def add_friction(subparsers) -> None:
    """The ``friction`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "friction",
        "constant-speed runs both ways: the steady torque against speed, fitted to Coulomb, "
        "viscous and Stribeck terms per direction, written as plant.yaml",
        run_friction,
    )
    number_options(parser, FRICTION_NUMBERS)
    parser.add_argument(
        "--measured",
        metavar="RUNS.csv",
        help="fit a measured file of constant-speed runs instead: t [s], torque [N.m] or "
        "current [A], motor_speed [rad/s] or x [m] (default: the twin's runs)",
    )
    axis_test_options(parser, "out/friction-<scenario name>")


def run_friction(args: argparse.Namespace) -> int:
    """Run (or read) the levels, fit, write friction.json, friction.txt, friction.csv,
    plant.yaml and friction.png; print the table."""
    import dataclasses

    import numpy as np
    import pandas as pd

    from twin_cosim.scenario.plant_parameters import write_plant_parameters
    from twin_cosim.servo.friction import (
        default_speeds,
        describe,
        friction_curve,
        measured_curve,
        plant_file,
        plot_friction,
    )

    def levels(plant, scenario):  # type: ignore[no-untyped-def]
        top = args.max_speed or float(default_speeds(scenario)[0])
        if not top > args.min_speed:
            raise ValueError(
                f"--max-speed {top:g} rad/s: expected above --min-speed {args.min_speed:g} rad/s"
            )
        speeds = np.geomspace(top, args.min_speed, args.levels)
        return friction_curve(plant, scenario, speeds, args.dwell)

    if args.measured:
        scenario, warnings = scenario_of(args)
        out = out_folder(args.out, Path("out") / f"friction-{scenario.name}")
        result = measured_curve(args.measured, scenario)
        out.mkdir(parents=True, exist_ok=True)
    else:
        scenario, warnings, out, result = run_axis_test(args, "friction", levels)
    command = command_line("friction")
    plant_yaml = write_plant_parameters(out / "plant.yaml", plant_file(result, scenario, command))
    units = {"speed": "speed_rad_s", "torque": "torque_n_m", "speed_spread": "speed_spread_rad_s"}
    points = pd.DataFrame([dataclasses.asdict(p) for p in result.points]).rename(columns=units)
    points.to_csv(out / "friction.csv", index=False)
    files = {"points": str(out / "friction.csv"), "plant": str(plant_yaml)}
    if not args.no_plots:
        files["plot"] = str(plot_friction(result, out / "friction.png", command))
    summary = {**result.summary(), "scenario": str(scenario.source)}
    write_report(out, "friction", summary, describe(result), files, warnings, args.json)
    return 0
