"""``twin friction``: the friction curve as drives measure it, fitted, written as plant.yaml."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.console import (
    command_line,
    run_axis_test,
    scenario_of,
    write_report,
)
from twin_cosim.commands.options import (
    axis_test_options,
    axis_test_parser,
    number_above,
    number_options,
    out_folder,
    whole_number,
)

NUMBERS = (  # option, type, default, metavar, help
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


def add_arguments(subparsers) -> None:
    """The ``friction`` command and its options."""
    parser = axis_test_parser(
        subparsers,
        "friction",
        "constant-speed runs both ways: the steady torque against speed, fitted to Coulomb, "
        "viscous and Stribeck terms per direction, written as plant.yaml",
        run,
    )
    number_options(parser, NUMBERS)
    parser.add_argument(
        "--measured",
        metavar="RUNS.csv",
        help="fit a measured file of constant-speed runs instead: t [s], torque [N.m] or "
        "current [A], motor_speed [rad/s] or x [m] (default: the twin's runs)",
    )
    axis_test_options(parser, "out/friction-<scenario name>")


def run(args: argparse.Namespace) -> int:
    """Run (or read) the levels, fit, write friction.json, friction.txt, friction.csv,
    plant.yaml and friction.png; print the table."""
    import dataclasses

    import numpy as np
    import pandas as pd

    from twin_cosim.scenario.plant_file import write_plant_parameters
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
