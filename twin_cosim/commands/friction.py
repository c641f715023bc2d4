"""``twin friction``: the friction curve as drives measure it, fitted, written as plant.yaml."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin_cosim.commands.console import command_line, scenario_of, write_json, write_table
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    no_plots_option,
    number_above,
    out_folder,
    params_option,
    plant_option,
    plant_parameters_option,
    plant_path,
    whole_number,
)


def add_arguments(subparsers) -> None:
    """The ``friction`` command and its options."""
    parser = command_parser(
        subparsers,
        "friction",
        "constant-speed runs both ways: the steady torque against speed, fitted to Coulomb, "
        "viscous and Stribeck terms per direction, written as plant.yaml",
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--max-speed",
        type=number_above(0.0),
        metavar="RAD_S",
        help="the highest motor speed, rad/s (default: the scenario's fastest reference speed)",
    )
    parser.add_argument(
        "--min-speed",
        type=number_above(0.0),
        default=0.02,
        metavar="RAD_S",
        help="the lowest motor speed, rad/s",
    )
    parser.add_argument(
        "--levels", type=whole_number(3), default=24, help="speeds per direction, log-spaced"
    )
    parser.add_argument(
        "--dwell", type=number_above(0.0), default=0.5, metavar="S", help="time at each speed, s"
    )
    parser.add_argument(
        "--measured",
        metavar="RUNS.csv",
        help="fit a measured file of constant-speed runs instead: t [s], torque [N.m] or "
        "current [A], motor_speed [rad/s] or x [m] (default: the twin's runs)",
    )
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    parser.add_argument(
        "--out", metavar="DIR", help="output folder (default: out/friction-<scenario name>)"
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    no_plots_option(parser)
    data_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run (or read) the levels, fit, write friction.json, friction.txt, friction.csv,
    plant.yaml and friction.png; print the table."""
    import numpy as np
    import pandas as pd

    from twin_cosim.plant import Plant
    from twin_cosim.scenario.plant_file import write_plant_parameters
    from twin_cosim.servo.friction import (
        default_speeds,
        describe,
        friction_curve,
        measured_curve,
        plant_file,
        plot_friction,
    )
    from twin_cosim.versions import versions

    scenario, mismatch = scenario_of(args)
    out = out_folder(args.out, Path("out") / f"friction-{scenario.name}")
    if args.measured:
        result = measured_curve(args.measured, scenario)
    else:
        top = args.max_speed or float(default_speeds(scenario)[0])
        if not top > args.min_speed:
            raise ValueError(
                f"--max-speed {top:g} rad/s: expected above --min-speed {args.min_speed:g} rad/s"
            )
        speeds = np.geomspace(top, args.min_speed, args.levels)
        with Plant(scenario.plant_fmu(plant_path(args))) as plant:
            result = friction_curve(plant, scenario, speeds, args.dwell)
    out.mkdir(parents=True, exist_ok=True)
    command = command_line("friction")
    table = describe(result)
    files = {
        "table": str(write_table(out / "friction.txt", command, table)),
        "points": str(out / "friction.csv"),
        "plant": str(
            write_plant_parameters(out / "plant.yaml", plant_file(result, scenario, command))
        ),
    }
    pd.DataFrame(
        {
            "speed_rad_s": [p.speed for p in result.points],
            "torque_n_m": [p.torque for p in result.points],
            "speed_spread_rad_s": [p.speed_spread for p in result.points],
            "kind": [p.kind for p in result.points],
        }
    ).to_csv(out / "friction.csv", index=False)
    if not args.no_plots:
        files["plot"] = str(plot_friction(result, out / "friction.png", command))
    summary = {
        **result.summary(),
        "scenario": str(scenario.source),
        "command": command,
        "outputs": files,
        "warnings": mismatch,
        "versions": versions(),
    }
    write_json(out / "friction.json", summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print(table, end="")
        print(f"wrote {', '.join(files.values())}, {out / 'friction.json'}")
    return 0
