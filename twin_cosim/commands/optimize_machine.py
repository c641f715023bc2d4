"""``twin optimize MACHINE``: every axis' parameters tuned on circles or a part program.

The machine branch of :mod:`twin_cosim.commands.optimize` (a scenario with ``axes:``); the
campaign is :mod:`twin_cosim.contour.tuning_campaign`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin_cosim.commands.options import out_folder
from twin_cosim.optimize.methods import method_label

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
    """Run (or resume) the machine's campaign; print its result."""
    from twin_cosim.contour.tuning_campaign import ContourCampaignSpec, run_contour_campaign

    for option in _SINGLE_AXIS_OPTIONS:
        if getattr(args, option, None):
            raise ValueError(f"--{option.replace('_', '-')}: for single-axis scenarios only")
    if len(args.scenario) > 1:
        raise ValueError("a machine's campaign takes one machine scenario (its circles grid)")
    if args.resume:
        out = Path(args.resume)
        header = out / "campaign.json"
        if not header.is_file():
            raise ValueError(f"--resume {out}: no campaign.json to resume from")
        stored = json.loads(header.read_text())["spec"]
        given = {
            k: v
            for k, v in {
                "method": args.method,
                "seed": args.seed,
                "budget": args.budget,
                "program": args.program,
                "target": args.target,
                "start": args.start,
            }.items()
            if v is not None
        }
        spec = ContourCampaignSpec(**{**stored, **given, "scenario": args.scenario[0]})
        if args.no_early_stop:
            spec = ContourCampaignSpec(**{**spec.__dict__, "early_stop": False})
    else:
        if args.method is None:
            raise ValueError("--method is required unless --resume is given")
        spec = ContourCampaignSpec(
            scenario=args.scenario[0],
            method=args.method,
            seed=args.seed or 0,
            budget=args.budget,
            program=args.program,
            target=args.target,
            early_stop=not args.no_early_stop,
            start=args.start,
        )
        out = out_folder(args.out, Path("out") / f"optimize-machine-{spec.method}-seed{spec.seed}")
    try:
        result = run_contour_campaign(
            spec, out, workers=args.workers, resume=bool(args.resume), progress=not args.quiet
        )
    except KeyboardInterrupt as exc:
        if (out / "campaign.json").exists():
            exc.hint = f"; the log is intact: twin optimize {args.scenario[0]} --resume {out}"
        raise
    if args.json:
        print(json.dumps(result))
        return 0
    metrics = result["metrics"] or {}
    print(
        f"{method_label(spec.method)}: fitness {result['fitness']:.3f} um (reference sets: "
        f"{result['reference_fitness']:.3f} um), largest {result['target']} "
        f"{metrics.get(result['target'], float('nan')):.3f} um, after {result['evaluations']} "
        f"evaluations in {result['wall_s']:.1f} s; {result['stop_reason']}"
    )
    for axis, params in result["best_params"]["axes"].items():
        print(f"  {axis}: " + ", ".join(f"{k}={v:.6g}" for k, v in params.items()))
    print(f"wrote {out}/result.json (twin circle ... --params {out}/result.json)")
    return 0
