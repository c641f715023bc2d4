"""``twin optimize``: tune K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] in a campaign folder.

A machine scenario (``axes:``) tunes every axis' parameters on circles or a part program: its
problem is :class:`twin_cosim.contour.tuning.MachineProblem`, run by the same campaign driver.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

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
    whole_number,
)
from twin_cosim.optimize.algorithms import METHOD_NAMES, method_label, method_list

if TYPE_CHECKING:
    from twin_cosim.optimize.driver import CampaignResult
    from twin_cosim.workers import ProcessPool, SerialPool


SETTLING_WEIGHT = 0.05  # um of fitness per ms of settling time: --objective settling

if TYPE_CHECKING:
    from twin_cosim.optimize.axis_problem import CampaignSpec
    from twin_cosim.optimize.driver import CampaignResult
    from twin_cosim.painter import Painter
    from twin_cosim.workers import ProcessPool, SerialPool


def add_optimize(subparsers) -> None:
    """The ``optimize`` command and its options."""
    parser = command_parser(
        subparsers, "optimize", "tune K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H]", run_optimize
    )
    parser.add_argument(
        "scenario",
        nargs="+",
        help="scenario YAML file or shipped name (its optimize section); more scenarios: a "
        "robust objective over all of them",
    )
    _campaign_options(parser)
    plant_parameters_option(parser)
    _robust_options(parser)
    _machine_options(parser)
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    quiet_option(parser, "no progress bar")
    no_plots_option(parser)
    data_option(parser)


def _machine_options(parser: argparse.ArgumentParser) -> None:
    """For a machine scenario (axes:): a part program instead of the circles, the target."""
    parser.add_argument(
        "--program",
        metavar="PART.nc",
        help="machine scenarios: tune on this part program (target contour) instead of the "
        "scenario's circles (default: the circles of optimize.circles)",
    )
    parser.add_argument(
        "--target",
        choices=["G", "spike", "contour"],
        help="machine scenarios: worst case of G, the largest reversal spike or the largest "
        "contour error (default: the scenario's optimize.target, else G)",
    )
    parser.add_argument(
        "--start",
        metavar="SET_OR_FILE",
        help="start from a controller set (ft|ga|ce|sa or a file). One axis: the set (e.g. the "
        "autotune.json of twin autotune) becomes every scenario's own set, the start point and "
        "the reference of the IAU cap. A machine (axes:): the search starts from these sets (one "
        "set, or axes: {X: ..., Y: ...}, e.g. an earlier result.json), the scores stay relative "
        "to the scenario's own sets (default: the scenario's own sets)",
    )


def _campaign_options(parser: argparse.ArgumentParser) -> None:
    """Method, seed, budget, where it runs, the plant and the campaign folder."""
    parser.add_argument(
        "--method", choices=METHOD_NAMES, help="optimizer (default: none; required unless --resume)"
    )
    parser.add_argument("--seed", type=whole_number(0), help="seed (default: 0)")
    budget_option(parser, "maximum evaluations (default: the method's)")
    pool_options(
        parser,
        "local processes (default: all cores; 1: serial)",
        "Dask scheduler address, e.g. tcp://host:8786 (default: none, a local pool)",
    )
    plant_option(parser)
    parser.add_argument(
        "--out", metavar="DIR", help="campaign folder (default: out/optimize-<method>-seed<N>)"
    )
    parser.add_argument(
        "--resume", metavar="DIR", help="campaign folder to resume (default: a new campaign)"
    )


def _robust_options(parser: argparse.ArgumentParser) -> None:
    """Plant samples, how runs combine, and early stopping."""
    parser.add_argument(
        "--tolerance",
        type=float,
        help="relative tolerance of the uncertain plant parameters (default: 0, no samples)",
    )
    parser.add_argument(
        "--samples",
        type=whole_number(1),
        help="plant samples per scenario, the first nominal (default: 4 within the intervals "
        "of a --plant-parameters file that has them, as twin diagnose writes; else 1; "
        "--samples 1 tunes on the calibrated plant alone)",
    )
    parser.add_argument(
        "--objective",
        type=objective_terms,
        metavar="TERMS",
        help="comma-separated: worst or mean (how the runs over scenarios x samples combine), "
        "and settling[=W] (add W um per ms of each run's settling time after reversals and "
        f"stops, W {SETTLING_WEIGHT:g} when not given), e.g. settling, mean,settling=0.1 "
        "(default: worst, E_pk alone: the paper's objective, eq. (12))",
    )
    parser.add_argument(
        "--relative",
        action="store_true",
        help="score each run's E_pk relative to the reference set's (Fine-Tune) on the same "
        "scenario and plant sample, so that no scenario outweighs the others by being harder "
        "(default: off, E_pk in um)",
    )
    parser.add_argument(
        "--no-early-stop",
        action="store_true",
        help="run every candidate to the end (early stopping is exact; this is for measuring it)",
    )


def objective_terms(text: str) -> dict[str, Any]:
    """An argparse type: ``--objective`` as the campaign options it sets (``aggregate``,
    ``settling_weight``)."""
    terms: dict[str, Any] = {}
    for term in text.split(","):
        name, _, value = term.strip().partition("=")
        if name in ("worst", "mean") and not value and "aggregate" not in terms:
            terms["aggregate"] = name
        elif name == "settling" and "settling_weight" not in terms:
            try:
                weight = float(value) if value else SETTLING_WEIGHT
            except ValueError:
                weight = math.nan
            if not (math.isfinite(weight) and weight >= 0):
                raise argparse.ArgumentTypeError(
                    f"settling={value}: expected a weight >= 0 in um per ms, got {value!r}"
                )
            terms["settling_weight"] = weight
        else:
            raise argparse.ArgumentTypeError(
                f"expected worst or mean and/or settling[=W], comma-separated, got {text!r}"
            )
    return terms


def run_optimize(args: argparse.Namespace) -> int:
    """Run (or resume) the campaign, print its result, then write its plots.

    A machine scenario (axes:) runs its own campaign; otherwise the painter of the figures
    (which loads matplotlib meanwhile) and the pool's processes start first, so that they load
    while this process reads the campaign.
    """
    from twin_cosim.painter import Painter
    from twin_cosim.scenario import is_machine_scenario
    from twin_cosim.workers import make_pool, prepare_campaign_worker

    if is_machine_scenario(args.scenario[0]):
        return run_machine_campaign(args)
    if args.program or args.target:
        raise ValueError("--program and --target: for a machine scenario (axes:)")
    local = 1 if args.scheduler else args.workers  # with Dask: the reference runs here
    painter = None if args.no_plots else Painter.start()
    try:
        with make_pool(None, local, prepare_campaign_worker) as pool:
            return _run_on(args, pool, painter)
    finally:
        if painter is not None:
            painter.close()


def _run_on(
    args: argparse.Namespace, pool: SerialPool | ProcessPool, painter: Painter | None
) -> int:
    """The campaign and its result with ``pool`` running the plant; its plots drawn by
    ``painter`` (None: no plots). 1 when the plots could not be drawn."""
    from twin_cosim.optimize.axis_problem import AxisProblem
    from twin_cosim.optimize.driver import run_campaign

    spec, out = _spec_and_folder(args)
    problem = AxisProblem.resolve(spec)
    if painter is not None:  # the painter resolves it as this process did
        from twin_cosim.optimize.outputs import start_campaign_plots

        start_campaign_plots(spec, painter)
    if not args.resume:
        warn_plant_mismatch(problem.scenarios[0], plant_path(args))
    try:
        result = run_campaign(
            problem,
            out,
            scheduler=args.scheduler,
            resume=bool(args.resume),
            progress=not args.quiet,
            pool=pool,
        )
    except KeyboardInterrupt as exc:
        if (out / "campaign.json").exists():
            scenarios_given = " ".join(args.scenario)
            exc.hint = f"; the log is intact: twin optimize {scenarios_given} --resume {out}"
        raise
    _report(spec, result, out, args.json)
    drawn = True
    if painter is not None:
        from twin_cosim.optimize.outputs import write_campaign_plots

        sys.stdout.flush()  # the result shows while the figures are drawn
        drawn = write_campaign_plots(out, spec, painter)
    if not args.json:
        plots = ", convergence.png, best_run.png" if painter is not None and drawn else ""
        print(f"wrote {out}/result.json, evaluations.jsonl{plots}")
    return 0 if drawn else 1


def _given(args: argparse.Namespace) -> dict[str, Any]:
    """The campaign options given on the command line (those not given are left out)."""
    given = {
        "method": args.method,
        "seed": args.seed,
        "budget": args.budget,
        "plant_parameters": args.plant_parameters,
        "scenarios": list(args.scenario[1:]) or None,
        "tolerance": args.tolerance,
        "samples": args.samples,
        **(args.objective or {}),
        "relative": True if args.relative else None,
        "early_stop": False if args.no_early_stop else None,
        "start": args.start,
    }
    return {k: v for k, v in given.items() if v is not None}


def _spec_and_folder(args: argparse.Namespace) -> tuple[CampaignSpec, Path]:
    """The campaign asked for and its folder: a new one, or the stored one with what is given.

    On a resume, the campaign refuses given options that differ from the stored ones.
    """
    from twin_cosim.optimize.axis_problem import CampaignSpec, load_campaign_spec

    given = _given(args)
    if args.resume:
        out = Path(args.resume)
        stored = load_campaign_spec(out)
        fmu = args.plant or stored.fmu
        return dataclasses.replace(stored, scenario=args.scenario[0], fmu=fmu, **given), out
    if args.method is None:
        raise ValueError(f"--method is required ({method_list()}) unless --resume is given")
    spec = CampaignSpec(scenario=args.scenario[0], fmu=args.plant, **given)
    return spec, out_folder(args.out, Path("out") / f"optimize-{spec.method}-seed{spec.seed}")


def _best(result: CampaignResult) -> str:
    """The best candidate's outcome in words: its E_pk, or why no run was valid."""
    if result.metrics is None:
        return (
            f"no valid run (the best candidate's status: {result.status}; its score "
            f"{result.fitness:.4g} um is a penalty; see evaluations.jsonl)"
        )
    best = f"best E_pk {result.metrics['E_pk_um']:.3f} um"
    settling = result.metrics.get("settling_ms")
    if settling is not None:
        best += f", settling {settling:.1f} ms (fitness {result.fitness:.3f} um)"
    return best if result.status == "ok" else f"{best}, above the IAU cap (penalised)"


def _report(spec: CampaignSpec, result: CampaignResult, out: Path, as_json: bool) -> None:
    """Print the result: one JSON object, or lines for a reader."""
    if as_json:
        summary = {
            "best_params": result.best_params,
            "metrics": result.metrics,
            "reference_metrics": result.reference,
            "evaluations": result.evaluations,
            "evaluations_reused": result.evaluations_reused,
            "generations": result.generations,
            "stop_reason": result.stop_reason,
            "wall_s": result.wall_s,
            "out": str(out),
        }
        print(json.dumps(summary))
        return
    print(
        f"{method_label(spec.method)}: {_best(result)} (reference "
        f"{result.reference['E_pk_um']:.3f} um) after {result.evaluations} evaluations in "
        f"{result.wall_s:.1f} s; {result.stop_reason}"
    )
    print("best parameters: " + ", ".join(f"{k}={v:.6g}" for k, v in result.best_params.items()))


_SINGLE_AXIS_OPTIONS = (
    "plant",
    "plant_parameters",
    "tolerance",
    "samples",
    "objective",
    "relative",
    "scheduler",
)


def run_machine_campaign(args: argparse.Namespace) -> int:
    """Run (or resume) the machine's campaign; print its result.

    The pool's processes start first, so that they load the co-simulation while this process
    reads the machine.
    """
    from twin_cosim.contour.tuning import prepare_machine_worker
    from twin_cosim.workers import make_pool

    for option in _SINGLE_AXIS_OPTIONS:
        if getattr(args, option, None):
            raise ValueError(f"--{option.replace('_', '-')}: for single-axis scenarios only")
    if len(args.scenario) > 1:
        raise ValueError("a machine's campaign takes one machine scenario (its circles grid)")
    with make_pool(None, args.workers, prepare_machine_worker) as pool:
        return _run_machine_on(args, pool)


def _run_machine_on(args: argparse.Namespace, pool: SerialPool | ProcessPool) -> int:
    """The campaign and its result with ``pool`` running the plants."""
    from twin_cosim.contour.tuning import ContourCampaignSpec, MachineProblem, load_contour_spec
    from twin_cosim.optimize.driver import run_campaign

    given = {
        "method": args.method,
        "seed": args.seed,
        "budget": args.budget,
        "program": args.program,
        "target": args.target,
        "start": args.start,
        "early_stop": False if args.no_early_stop else None,
    }
    given = {k: v for k, v in given.items() if v is not None}
    if args.resume:
        out = Path(args.resume)
        spec = dataclasses.replace(load_contour_spec(out), scenario=args.scenario[0], **given)
    else:
        if args.method is None:
            raise ValueError("--method is required unless --resume is given")
        spec = ContourCampaignSpec(scenario=args.scenario[0], **given)
        out = out_folder(args.out, Path("out") / f"optimize-machine-{spec.method}-seed{spec.seed}")
    problem = MachineProblem.load(spec)
    try:
        result = run_campaign(
            problem, out, resume=bool(args.resume), progress=not args.quiet, pool=pool
        )
    except KeyboardInterrupt as exc:
        if (out / "campaign.json").exists():
            exc.hint = f"; the log is intact: twin optimize {args.scenario[0]} --resume {out}"
        raise
    if args.json:
        print(json.dumps(result.as_dict()))
        return 0
    print(f"{method_label(spec.method)}: {_outcome(result)}")
    print(
        f"  after {result.evaluations} evaluations in {result.wall_s:.1f} s; {result.stop_reason}"
    )
    for axis, params in result.best_params["axes"].items():
        print(f"  {axis}: " + ", ".join(f"{k}={v:.6g}" for k, v in params.items()))
    print(f"wrote {out}/result.json (twin circle ... --params {out}/result.json)")
    return 0


def _outcome(result: CampaignResult) -> str:
    """The best candidate's worst case and the target's largest value, against the reference
    sets, in words: a relative score as a ratio (each case scored against the reference sets'
    value on it), values in um."""
    details = result.details
    target = details["target"]
    metrics = result.metrics
    if metrics is None:
        return (
            f"no valid run (the best candidate's status: {result.status}; its score "
            f"{result.fitness:.4g} is a penalty; see evaluations.jsonl)"
        )
    cases = details["cases"]
    reference = {case: values[target] for case, values in zip(cases, result.reference, strict=True)}
    worst, largest = metrics["worst_case"], metrics[f"{target}_case"]
    if details["relative"]:
        ratio = result.fitness / details["reference_fitness"]
        head = f"worst case {worst} at {ratio:.3f} of the reference sets' {target} on it"
    else:
        head = f"worst case {worst}"
    text = (
        f"{head} ({target} {metrics[f'worst_case_{target}']:.3f} um, reference sets "
        f"{reference[worst]:.3f} um); largest {target} {metrics[target]:.3f} um on {largest} "
        f"(reference sets {reference[largest]:.3f} um)"
    )
    return text if result.status == "ok" else f"{text}, above an IAU cap (penalised)"
