"""``twin step``: the position step and settling test of an axis, as a drive runs it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin_cosim.commands.console import (
    command_line,
    scenario_of,
    write_json,
    write_record_csv,
    write_table,
)
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
)


def add_arguments(subparsers) -> None:
    """The ``step`` command and its options."""
    parser = command_parser(
        subparsers,
        "step",
        "a position step at standstill: rise time, overshoot, settling time to a band, the tail",
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--size",
        type=float,
        default=0.1,
        metavar="MM",
        help="the step of the position setpoint, mm (negative: backwards)",
    )
    parser.add_argument(
        "--band",
        type=number_above(0.0),
        default=1.0,
        metavar="UM",
        help="the settling band, um: settled once |x - setpoint| stays within it",
    )
    parser.add_argument(
        "--duration",
        type=number_above(0.0),
        default=0.5,
        metavar="S",
        help="how long the record runs after the step, s",
    )
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    parser.add_argument(
        "--out", metavar="DIR", help="output folder (default: out/step-<scenario name>)"
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    no_plots_option(parser)
    data_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the step, write step.json, step.txt, step.csv and step.png; print the table."""
    from twin_cosim.plant import Plant
    from twin_cosim.servo.step import describe, plot_step, step_test
    from twin_cosim.versions import versions

    scenario, mismatch = scenario_of(args)
    out = out_folder(args.out, Path("out") / f"step-{scenario.name}")
    with Plant(scenario.plant_fmu(plant_path(args))) as plant:
        result = step_test(plant, scenario, args.size * 1e-3, args.duration, args.band)
    out.mkdir(parents=True, exist_ok=True)
    command = command_line("step")
    files = {"record": str(out / "step.csv"), "table": str(out / "step.txt")}
    write_record_csv(out / "step.csv", result.record)
    table = describe(result)
    write_table(out / "step.txt", command, table)
    if not args.no_plots:
        files["plot"] = str(plot_step(result, out / "step.png", command))
    summary = {
        **result.summary(),
        "command": command,
        "outputs": files,
        "warnings": mismatch,
        "versions": versions(),
    }
    write_json(out / "step.json", summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print(table, end="")
        if summary["current_limited"]:
            print(
                f"twin step: note: the current reached its limit "
                f"({result.current_limit:g} A): the step is too large for a linear response"
            )
        print(f"wrote {', '.join(files.values())}, {out / 'step.json'}")
    return 0
