"""``twin compare``: several methods on one campaign file, the paper's Tables 3-5."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from twin_cosim.commands.options import (
    command_parser,
    data_option,
    no_plots_option,
    out_folder,
    plant_parameters_option,
    whole_number,
)


def add_arguments(subparsers) -> None:
    """The ``compare`` command and its options."""
    parser = command_parser(
        subparsers, "compare", "several methods on one campaign file: Tables 3-5", run
    )
    parser.add_argument("campaign", help="campaign YAML file (see scenarios/paper_campaign.yaml)")
    parser.add_argument(
        "--methods",
        help="comma-separated subset of the campaign's methods (default: all of them)",
    )
    parser.add_argument(
        "--budget",
        type=whole_number(1),
        help="evaluations of every method (default: the campaign file's budgets: {METHOD: N}, "
        "else each method's own)",
    )
    parser.add_argument(
        "--workers", type=whole_number(1), help="local processes (default: all cores)"
    )
    parser.add_argument(
        "--scheduler", metavar="ADDR", help="Dask scheduler address (default: none, a local pool)"
    )
    parser.add_argument("--out", metavar="DIR", help="output folder (default: out/<campaign name>)")
    plant_parameters_option(parser)
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    no_plots_option(parser)
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Run (or reuse) each method's campaign and write the tables, then the figures.

    One pool serves every method; its processes start first, so that they load the
    co-simulation while this process reads the campaign file.
    """
    from twin_cosim.pool_runs import prepare_campaign_worker
    from twin_cosim.workers import make_pool

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
