"""``twin optimize MACHINE``: every axis' parameters tuned on circles or a part program.

The machine branch of :mod:`twin_cosim.commands.optimize` (a scenario with ``axes:``); the
problem is :class:`twin_cosim.contour.tuning.MachineProblem`, run by the campaign driver.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path
from typing import TYPE_CHECKING

from twin_cosim.commands.options import out_folder
from twin_cosim.optimize.algorithms import method_label

if TYPE_CHECKING:
    from twin_cosim.optimize.driver import CampaignResult
    from twin_cosim.workers import ProcessPool, SerialPool

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
        return _run_on(args, pool)


def _run_on(args: argparse.Namespace, pool: SerialPool | ProcessPool) -> int:
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
