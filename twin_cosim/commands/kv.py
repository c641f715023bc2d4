"""``twin kv``: the following error against speed and the position-loop gain Kv."""

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
)


def add_arguments(subparsers) -> None:
    """The ``kv`` command and its options."""
    parser = command_parser(
        subparsers, "kv", "the following error at constant speeds and the position gain Kv"
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
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
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    parser.add_argument(
        "--out", metavar="DIR", help="output folder (default: out/kv-<scenario name>)"
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    no_plots_option(parser)
    data_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the speed levels, write kv.json, kv.txt and kv.png; print the table."""
    from twin_cosim.plant import Plant
    from twin_cosim.servo.following import describe, following_test, plot_following
    from twin_cosim.versions import versions

    scenario, mismatch = scenario_of(args)
    out = out_folder(args.out, Path("out") / f"kv-{scenario.name}")
    with Plant(scenario.plant_fmu(plant_path(args))) as plant:
        result = following_test(plant, scenario, args.speeds, args.dwell)
    out.mkdir(parents=True, exist_ok=True)
    command = command_line("kv")
    table = describe(result)
    files = {"table": str(write_table(out / "kv.txt", command, table))}
    if not args.no_plots:
        files["plot"] = str(plot_following(result, out / "kv.png", command))
    summary = {
        **result.summary(),
        "command": command,
        "outputs": files,
        "warnings": mismatch,
        "versions": versions(),
    }
    write_json(out / "kv.json", summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print(table, end="")
        print(f"wrote {', '.join(files.values())}, {out / 'kv.json'}")
    return 0
