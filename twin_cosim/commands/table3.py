"""``twin table3``: the paper's Table 3 parameter sets run on scenarios."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from twin_cosim.commands.console import warn_plant_mismatch
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    out_folder,
    plant_option,
    plant_path,
)

if TYPE_CHECKING:
    pass


def add_arguments(subparsers) -> None:
    """The ``table3`` command and its options."""
    parser = command_parser(
        subparsers, "table3", "run the paper's Table 3 parameter sets on scenarios", run
    )
    parser.add_argument("scenarios", nargs="+", help="scenario YAML files or shipped names")
    plant_option(parser)
    parser.add_argument("--out", metavar="DIR", help="output folder (default: out/table3)")
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Run every set on every scenario; write table3.md, table3.csv and the error plots."""
    from twin_cosim import paper
    from twin_cosim.controller_set import ControllerSet
    from twin_cosim.report import evaluate_sets, markdown_table, plot_set_errors
    from twin_cosim.scenario import resolve_scenario
    from twin_cosim.workers import SerialPool

    scenarios = {str(path): resolve_scenario(path) for path in args.scenarios}
    for scenario in scenarios.values():
        warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / "table3")
    out.mkdir(parents=True, exist_ok=True)
    sets = {name.upper(): ControllerSet(tuned) for name, tuned in paper.TABLE3.items()}
    first = next(iter(scenarios.values()))
    with SerialPool() as pool:
        table, records = evaluate_sets(pool, first.plant_fmu(plant_path(args)), scenarios, sets)
    table.to_csv(out / "table3.csv")
    flat = table.reset_index().set_index("set")
    text = "".join(
        f"\n{name}:\n\n" + markdown_table(flat[flat["scenario"] == name].drop(columns="scenario"))
        for name in table.index.unique(level="scenario")
    )
    (out / "table3.md").write_text(text)
    plot_set_errors(
        scenarios,
        sets,
        records,
        "paper Table 3 parameter sets",
        lambda _, scenario: out / f"{scenario.name}_errors.png",
    )
    print(text)
    print(f"wrote {out}/table3.md, table3.csv and error plots")
    return 0
