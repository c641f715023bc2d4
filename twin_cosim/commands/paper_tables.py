"""The paper's tables on the twin: ``twin table3`` runs the Table 3 parameter sets on
scenarios, ``twin compare`` runs several methods on one campaign file (Tables 3-5).
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from twin_cosim.commands.console import warn_plant_mismatch
from twin_cosim.commands.options import (
    budget_option,
    command_parser,
    data_option,
    no_plots_option,
    out_folder,
    plant_option,
    plant_parameters_option,
    plant_path,
    pool_options,
    quiet_option,
)


def add_table3(subparsers) -> None:
    """The ``table3`` command and its options."""
    parser = command_parser(
        subparsers, "table3", "run the paper's Table 3 parameter sets on scenarios", run_table3
    )
    parser.add_argument("scenarios", nargs="+", help="scenario YAML files or shipped names")
    plant_option(parser)
    parser.add_argument("--out", metavar="DIR", help="output folder (default: out/table3)")
    data_option(parser)


def run_table3(args: argparse.Namespace) -> int:
    """Run every set on every scenario; write table3.md, table3.csv and the error plots."""
    from twin_cosim.controller_set import TABLE3, ControllerSet
    from twin_cosim.report import evaluate_sets, markdown_table, plot_set_errors
    from twin_cosim.scenario import resolve_scenario
    from twin_cosim.workers import SerialPool

    scenarios = {str(path): resolve_scenario(path) for path in args.scenarios}
    for scenario in scenarios.values():
        warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / "table3")
    out.mkdir(parents=True, exist_ok=True)
    sets = {name.upper(): ControllerSet(tuned) for name, tuned in TABLE3.items()}
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


def add_compare(subparsers) -> None:
    """The ``compare`` command and its options."""
    parser = command_parser(
        subparsers, "compare", "several methods on one campaign file: Tables 3-5", run_compare
    )
    parser.add_argument("campaign", help="campaign YAML file (see scenarios/paper_campaign.yaml)")
    parser.add_argument(
        "--methods",
        help="comma-separated subset of the campaign's methods (default: all of them)",
    )
    budget_option(
        parser,
        "evaluations of every method (default: the campaign file's budgets: {METHOD: N}, else "
        "each method's own)",
    )
    pool_options(
        parser,
        "local processes (default: all cores)",
        "Dask scheduler address (default: none, a local pool)",
    )
    parser.add_argument("--out", metavar="DIR", help="output folder (default: out/<campaign name>)")
    plant_parameters_option(parser)
    quiet_option(parser, "no progress bars")
    no_plots_option(parser)
    data_option(parser)


def run_compare(args: argparse.Namespace) -> int:
    """Run (or reuse) each method's campaign and write the tables, then the figures.

    One pool serves every method; its processes start first, so that they load the
    co-simulation while this process reads the campaign file.
    """
    from twin_cosim.workers import make_pool, prepare_campaign_worker

    with make_pool(None, 1 if args.scheduler else args.workers, prepare_campaign_worker) as pool:
        from twin_cosim.optimize.comparison import load_comparison, run_comparison

        comparison = load_comparison(Path(args.campaign))
        if args.plant_parameters:
            comparison = dataclasses.replace(
                comparison, plant_parameters=Path(args.plant_parameters)
            )
        if args.budget:
            comparison = dataclasses.replace(
                comparison, budgets=dict.fromkeys(comparison.methods, args.budget)
            )
        out = out_folder(args.out, Path("out") / comparison.name)
        text = run_comparison(
            comparison,
            out,
            methods=args.methods.split(",") if args.methods else None,
            scheduler=args.scheduler,
            progress=not args.quiet,
            plots=not args.no_plots,
            pool=pool,
        )
    print(text)
    figures = "" if args.no_plots else ", convergence.png and error plots"
    print(f"wrote {out}/tables.md, tables.json{figures}")
    return 0
