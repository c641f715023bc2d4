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
    from twin_cosim.controller_set import ControllerSet
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario


def add_arguments(subparsers) -> None:
    """The ``table3`` command and its options."""
    parser = command_parser(
        subparsers, "table3", "run the paper's Table 3 parameter sets on scenarios"
    )
    parser.add_argument("scenarios", nargs="+", help="scenario YAML files or shipped names")
    plant_option(parser)
    parser.add_argument("--out", metavar="DIR", help="output folder (default: out/table3)")
    data_option(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run every set on every scenario; write table3.md, table3.csv and the error plots."""
    from twin_cosim import paper
    from twin_cosim.controller_set import ControllerSet
    from twin_cosim.report import evaluate_sets, markdown_table
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
    _plot_errors(scenarios, sets, records, out)
    print(text)
    print(f"wrote {out}/table3.md, table3.csv and error plots")
    return 0


def _plot_errors(
    scenarios: dict[str, Scenario],
    sets: dict[str, ControllerSet],
    records: dict[tuple[str, str], RunRecord],
    out: Path,
) -> None:
    """One plot per scenario: the error of every set, around the Fine-Tune set's peak.

    ``records`` holds each run by (scenario label, set name).
    """
    from twin_cosim.metrics import compute_metrics
    from twin_cosim.plots import plot_error_comparison

    for label, scenario in scenarios.items():
        runs = {name: records[(label, name)] for name in sets}
        peak = compute_metrics(runs["FT"], scenario.metrics_window).t_E_pk
        plot_error_comparison(
            runs,
            peak,
            f"{scenario.name}: paper Table 3 parameter sets",
            out / f"{scenario.name}_errors.png",
        )
