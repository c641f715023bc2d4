"""The ``twin`` command line: build, simulate, optimize, compare."""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import time
from pathlib import Path
from typing import Any

from fmu_build.build import DEFAULT_MODEL, BuildError, available_models, build_fmu
from fmu_build.variable_table import VariableTableError
from twin_cosim.metrics import compute_metrics
from twin_cosim.plant import Plant, PlantError
from twin_cosim.reference import ReferenceError
from twin_cosim.scenario import ScenarioError, load_scenario, load_tuned_parameters

USER_ERRORS = (
    BuildError,
    VariableTableError,
    PlantError,
    ScenarioError,
    ReferenceError,
    ValueError,
)


def versions() -> dict[str, str]:
    """Versions of the software a result depends on."""
    from importlib.metadata import PackageNotFoundError, version

    found = {"python": platform.python_version()}
    for package in ("twin-cosim", "fmpy", "numpy", "scipy", "numba", "pandas"):
        try:
            found[package] = version(package)
        except PackageNotFoundError:
            found[package] = "not installed"
    return found


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2) + "\n")


def _build(args: argparse.Namespace) -> int:
    path = build_fmu(args.model, Path(args.out) if args.out else None, force=args.force)
    print(path)
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from twin_cosim.cosim import run_scenario
    from twin_cosim.plant_parameters import with_plant_parameters
    from twin_cosim.plots import plot_run

    scenario = with_plant_parameters(
        load_scenario(args.scenario), args.plant_parameters, args.plant
    )
    tuned = load_tuned_parameters(args.params) if args.params else scenario.tuned
    fmu = Path(args.plant) if args.plant else scenario.fmu
    out = Path(args.out) if args.out else Path("out") / scenario.name
    out.mkdir(parents=True, exist_ok=True)
    with Plant(fmu) as plant:
        start = time.perf_counter()
        record = run_scenario(plant, scenario, tuned, fast=not args.reference_path)
        wall = time.perf_counter() - start
        fmu_path = str(plant.fmu_path)
    metrics = compute_metrics(record, scenario.metrics_window)
    validation = None
    if scenario.measured is not None:
        from twin_cosim.measured import read_measured
        from twin_cosim.metrics import compare_with_measured

        run = read_measured(scenario.measured)
        validation = {
            "measured": str(scenario.measured),
            **compare_with_measured(record, run.t, run.x, run.current),
        }
    on_machine = None
    if args.machine:
        from twin_cosim.machine import machine_metrics, prediction

        judged, kind = machine_metrics(scenario, tuned, args.machine)
        on_machine = {"source": args.machine, "kind": kind, **prediction(metrics, judged)}
    record.to_csv(out / "record.csv", index=False)
    plot_run(
        record, metrics, f"{scenario.name}: {args.params or 'scenario parameters'}", out / "run.png"
    )
    summary = {
        "scenario": str(scenario.source),
        "fmu": fmu_path,
        "plant_parameters_file": args.plant_parameters,
        "params": tuned.as_dict(),
        "metrics": metrics.as_dict(),
        "validation": validation,
        "machine": on_machine,
        "metrics_window_s": list(scenario.metrics_window),
        "path": "reference (fmpy)" if args.reference_path else "fast (numba)",
        "wall_s": wall,
        "outputs": {"record": str(out / "record.csv"), "plot": str(out / "run.png")},
        "versions": versions(),
    }
    write_json(out / "summary.json", summary)
    if args.json:
        print(json.dumps(summary))
    else:
        m = metrics
        print(
            f"{scenario.name}: E_pk {m.E_pk_um:.2f} um, ITAE {m.ITAE:.2f} um.s^2, "
            f"IAU {m.IAU:.3f} A.s, "
            f"RMS {m.rms_um:.2f} um ({wall:.2f} s wall)"
        )
        if validation:
            v = validation
            print(
                f"against {v['measured']}: position gap RMS {v['position_rms_gap_um']:.3f} um "
                f"(max {v['position_max_gap_um']:.2f} um, relative "
                f"{v['position_relative_error_pct']:.4f} %), command/force relative error "
                f"{v['current_relative_error_pct']:.3f} %"
            )
        if on_machine:
            from twin_cosim.machine import JUDGED, describe

            print(describe(args.machine, on_machine["kind"], {k: on_machine[k] for k in JUDGED}))
        print(f"wrote {out}/record.csv, run.png, summary.json")
    return 0


def _table3(args: argparse.Namespace) -> int:
    from twin_cosim import paper
    from twin_cosim.plots import plot_error_comparison
    from twin_cosim.report import evaluate_sets, markdown_table

    scenarios = {str(path): load_scenario(path) for path in args.scenarios}
    out = Path(args.out) if args.out else Path("out") / "table3"
    out.mkdir(parents=True, exist_ok=True)
    sets = {name.upper(): tuned for name, tuned in paper.TABLE3.items()}
    first = next(iter(scenarios.values()))
    with Plant(Path(args.plant) if args.plant else first.fmu) as plant:
        table, records = evaluate_sets(plant, scenarios, sets)
    table.to_csv(out / "table3.csv")
    flat = table.reset_index().set_index("set")
    text = "".join(
        f"\n{name}:\n\n" + markdown_table(flat[flat["scenario"] == name].drop(columns="scenario"))
        for name in table.index.unique(level="scenario")
    )
    (out / "table3.md").write_text(text)
    for label, scenario in scenarios.items():
        runs = {name: records[(label, name)] for name in sets}
        peak = compute_metrics(runs["FT"], scenario.metrics_window).t_E_pk
        plot_error_comparison(
            runs,
            peak,
            f"{scenario.name}: paper Table 3 parameter sets",
            out / f"{scenario.name}_errors.png",
        )
    print(text)
    print(f"wrote {out}/table3.md, table3.csv and error plots")
    return 0


def _optimize(args: argparse.Namespace) -> int:
    from twin_cosim.optimize.campaign import CampaignSpec, load_spec, run_campaign
    from twin_cosim.optimize.outputs import write_campaign_plots

    if args.resume:
        spec = load_spec(Path(args.resume))
        given = {"method": args.method, "seed": args.seed, "budget": args.budget}
        given |= _robust_options(args)
        stored = {"method": spec.method, "seed": spec.seed, "budget": spec.budget}
        stored |= {k: getattr(spec, k) for k in _robust_options(args)}
        conflicts = {
            k: (v, stored[k]) for k, v in given.items() if v is not None and v != stored[k]
        }
        if conflicts:
            raise ValueError(
                f"--resume {args.resume}: options differ from the stored campaign: {conflicts}"
            )
        out = Path(args.resume)
    else:
        if args.method is None:
            raise ValueError(
                "--method is required (ce, ga, sa, cmaes or de) unless --resume is given"
            )
        robust = {k: v for k, v in _robust_options(args).items() if v is not None}
        spec = CampaignSpec(
            scenario=args.scenario[0],
            method=args.method,
            seed=0 if args.seed is None else args.seed,
            budget=args.budget,
            fmu=args.plant,
            **robust,
        )
        out = (
            Path(args.out) if args.out else Path("out") / f"optimize-{spec.method}-seed{spec.seed}"
        )
    result = run_campaign(
        spec,
        out,
        workers=args.workers,
        scheduler=args.scheduler,
        resume=bool(args.resume),
        progress=not args.quiet,
    )
    write_campaign_plots(out)
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
    if args.json:
        print(json.dumps(summary))
    else:
        m = result.metrics or {}
        print(
            f"{spec.method}: best E_pk {m.get('E_pk_um', float('nan')):.3f} um "
            f"(reference {result.reference['E_pk_um']:.3f} um) after {result.evaluations} "
            f"evaluations in {result.wall_s:.1f} s; {result.stop_reason}"
        )
        print(
            "best parameters: " + ", ".join(f"{k}={v:.6g}" for k, v in result.best_params.items())
        )
        print(f"wrote {out}/result.json, evaluations.jsonl, convergence.png, best_run.png")
    return 0


def _robust_options(args: argparse.Namespace) -> dict[str, Any]:
    """Options of a calibrated or robust campaign as given (None: not given)."""
    return {
        "plant_parameters": args.plant_parameters,
        "scenarios": list(args.scenario[1:]) or None,
        "tolerance": args.tolerance,
        "samples": args.samples,
        "aggregate": args.objective,
        "early_stop": False if args.no_early_stop else None,
    }


def _compare(args: argparse.Namespace) -> int:
    from twin_cosim.optimize.comparison import load_comparison, run_comparison

    comparison = load_comparison(Path(args.campaign))
    if args.plant_parameters:
        comparison = dataclasses.replace(comparison, plant_parameters=Path(args.plant_parameters))
    methods = args.methods.split(",") if args.methods else None
    out = Path(args.out) if args.out else Path("out") / comparison.name
    text = run_comparison(
        comparison,
        out,
        methods=methods,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=not args.quiet,
    )
    print(text)
    print(f"wrote {out}/tables.md, tables.json, convergence.png and error plots")
    return 0


def _synth(args: argparse.Namespace) -> int:
    from twin_cosim.gap.synth import parse_effect, synthesize

    scenario = load_scenario(args.scenario)
    effects = [parse_effect(text) for text in args.effect]
    synthesis = synthesize(
        scenario,
        effects,
        args.perturb,
        args.seed,
        Path(args.plant) if args.plant else None,
        args.noise_position,
        args.noise_current,
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    synthesis.run.to_csv(out, index=False)
    truth = out.with_name(out.name + ".truth.json")
    write_json(truth, synthesis.truth)
    print(f"wrote {out} ({len(synthesis.run)} samples) and the known answer in {truth}")
    return 0


def _diagnose(args: argparse.Namespace) -> int:
    from twin_cosim.gap.diagnosis import diagnose, settings_from
    from twin_cosim.gap.report import write_report
    from twin_cosim.measured import read_measured

    scenario = load_scenario(args.scenario)
    measured = [read_measured(path) for path in args.measured]
    holdout = [read_measured(path) for path in args.holdout or []]
    settings = settings_from(scenario, args.split)
    if args.max_effects is not None:
        settings = dataclasses.replace(settings, max_effects=args.max_effects)
    start = time.perf_counter()
    result = diagnose(scenario, measured, holdout, args.plant, settings, workers=args.workers)
    result.summary["wall_s"] = time.perf_counter() - start
    result.summary["versions"] = versions()
    out = Path(args.out) if args.out else Path("out") / f"diagnosis-{scenario.name}"
    with Plant(Path(args.plant) if args.plant else scenario.fmu) as plant:
        gear_ratio = plant.start_values().get("gear_ratio", 1.5)
    files = write_report(result, out, gear_ratio)
    files |= _write_calibration(args, scenario, result.summary, out)
    if args.json:
        print(json.dumps(result.summary))
    else:
        print(result.summary["gap"]["verdict"])
        for step in result.summary["steps"]:
            print(
                f"  {step['effect']}: held-out position gap {step['holdout_gap_before_um']:.3f} -> "
                f"{step['holdout_gap_after_um']:.3f} um, current "
                f"{step['holdout_current_before_A']:.4f} -> "
                f"{step['holdout_current_after_A']:.4f} A; fitted {step['params']}"
            )
        print(
            f"wrote {files['markdown']}, {files['html']}, {files['json']}, {files['plant']}, "
            f"{files['calibrated']} ({result.summary['wall_s']:.1f} s)"
        )
    return 0


def _write_calibration(
    args: argparse.Namespace, scenario, summary: dict[str, Any], out: Path
) -> dict[str, str]:
    """DIR/plant.yaml (the accepted effects and noise) and DIR/calibrated.yaml."""
    from twin_cosim.plant_parameters import (
        calibrated_scenario,
        fmu_model,
        from_diagnosis,
        write_plant_parameters,
    )

    runs = [f"--measured {m}" for m in args.measured] + [
        f"--holdout {h}" for h in args.holdout or []
    ]
    made_by = {
        "command": " ".join(["twin diagnose", str(args.scenario), *runs]),
        "version": versions()["twin-cosim"],
    }
    plant = from_diagnosis(summary, fmu_model(args.plant or scenario.fmu), made_by)
    plant_file = write_plant_parameters(out / "plant.yaml", plant)
    calibrated = calibrated_scenario(scenario.source, plant, out / "calibrated.yaml")
    return {"plant": str(plant_file), "calibrated": str(calibrated)}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``twin``."""
    parser = argparse.ArgumentParser(prog="twin", description="Digital twin of a CNC feed axis")
    commands = parser.add_subparsers(dest="command", required=True)

    build = commands.add_parser("build", help="build a plant FMU from models/<MODEL>")
    build.add_argument(
        "model", nargs="?", default=DEFAULT_MODEL, help=f"one of {available_models()}"
    )
    build.add_argument("--out", help="output folder (default: build/)")
    build.add_argument("--force", action="store_true", help="rebuild even if up to date")
    build.set_defaults(handler=_build)

    simulate = commands.add_parser("simulate", help="run a scenario in closed loop")
    simulate.add_argument("scenario", help="scenario YAML file")
    simulate.add_argument("--params", help="ft|ga|ce|sa (paper Table 3) or a YAML/JSON file")
    simulate.add_argument("--plant", help="another FMU offering the plant contract")
    simulate.add_argument(
        "--plant-parameters", help="calibrated plant parameters (plant.yaml of twin diagnose)"
    )
    simulate.add_argument(
        "--machine",
        help="judge on a machine: a measured run (CSV/.mat) made with these gains, or a virtual "
        "machine (a scenario or plant.yaml whose plant stands for the machine)",
    )
    simulate.add_argument("--out", help="output folder (default: out/<scenario name>)")
    simulate.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object"
    )
    simulate.add_argument(
        "--reference-path",
        action="store_true",
        help="step through fmpy in plain Python instead of the compiled loop",
    )
    simulate.set_defaults(handler=_simulate)

    optimize = commands.add_parser(
        "optimize", help="tune K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H]"
    )
    optimize.add_argument(
        "scenario",
        nargs="+",
        help="scenario YAML file (its optimize section); more files: a robust objective over all",
    )
    optimize.add_argument("--method", choices=["ce", "ga", "sa", "cmaes", "de"])
    optimize.add_argument("--seed", type=int, help="seed (default 0)")
    optimize.add_argument("--budget", type=int, help="maximum evaluations (default: the method's)")
    optimize.add_argument(
        "--workers", type=int, help="local processes (default: all cores; 1: serial)"
    )
    optimize.add_argument("--scheduler", help="Dask scheduler address, e.g. tcp://host:8786")
    optimize.add_argument("--plant", help="another FMU offering the plant contract")
    optimize.add_argument("--out", help="campaign folder (default: out/optimize-<method>-seed<N>)")
    optimize.add_argument(
        "--plant-parameters", help="calibrated plant parameters (plant.yaml of twin diagnose)"
    )
    optimize.add_argument(
        "--tolerance", type=float, help="relative tolerance of the uncertain plant parameters"
    )
    optimize.add_argument(
        "--samples", type=int, help="plant samples per scenario, the first nominal (default 1)"
    )
    optimize.add_argument(
        "--objective", choices=["worst", "mean"], help="over scenarios x samples (default worst)"
    )
    optimize.add_argument(
        "--no-early-stop",
        action="store_true",
        help="run every candidate to the end (early stopping is exact; this is for measuring it)",
    )
    optimize.add_argument("--resume", help="campaign folder to resume")
    optimize.add_argument("--json", action="store_true", help="print the result as one JSON object")
    optimize.add_argument("--quiet", action="store_true", help="no progress bar")
    optimize.set_defaults(handler=_optimize)

    compare = commands.add_parser(
        "compare", help="several methods on one campaign file: Tables 3-5"
    )
    compare.add_argument("campaign", help="campaign YAML file (see scenarios/paper_campaign.yaml)")
    compare.add_argument("--methods", help="comma-separated subset of the campaign's methods")
    compare.add_argument("--workers", type=int, help="local processes (default: all cores)")
    compare.add_argument("--scheduler", help="Dask scheduler address")
    compare.add_argument("--out", help="output folder (default: out/<campaign name>)")
    compare.add_argument(
        "--plant-parameters", help="calibrated plant parameters for every scenario (plant.yaml)"
    )
    compare.add_argument("--quiet", action="store_true", help="no progress bars")
    compare.set_defaults(handler=_compare)

    synth = commands.add_parser(
        "synth", help="the virtual machine: a measured run with known effects"
    )
    synth.add_argument("scenario", help="scenario YAML file")
    synth.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="effect to switch on (repeatable); NAME from the library or 'plant'",
    )
    synth.add_argument(
        "--perturb", type=float, default=0.0, help="calibration error, relative (e.g. 0.03)"
    )
    synth.add_argument("--seed", type=int, default=0)
    synth.add_argument(
        "--noise-position", type=float, default=20e-9, help="white noise on x, m (20e-9)"
    )
    synth.add_argument(
        "--noise-current", type=float, default=5e-3, help="white noise on the current, A"
    )
    synth.add_argument("--plant", help="another FMU offering the plant contract")
    synth.add_argument("--out", required=True, help="measured-run CSV to write")
    synth.set_defaults(handler=_synth)

    diag = commands.add_parser("diagnose", help="where the twin is wrong, why, and by how much")
    diag.add_argument("scenario", help="scenario YAML file the measured runs followed")
    diag.add_argument(
        "--measured", action="append", required=True, help="measured run (CSV or EMPS .mat)"
    )
    diag.add_argument("--holdout", action="append", help="held-out run(s); default: a time split")
    diag.add_argument(
        "--split", type=float, help="training fraction of the time split (default 0.5)"
    )
    diag.add_argument("--max-effects", type=int, help="effects to accept at most (default 3)")
    diag.add_argument("--plant", help="another FMU offering the plant contract")
    diag.add_argument(
        "--workers", type=int, help="local processes for the fits (default: all cores)"
    )
    diag.add_argument("--out", help="report folder (default: out/diagnosis-<scenario name>)")
    diag.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    diag.set_defaults(handler=_diagnose)

    table3 = commands.add_parser(
        "table3", help="run the paper's Table 3 parameter sets on scenarios"
    )
    table3.add_argument("scenarios", nargs="+", help="scenario YAML files")
    table3.add_argument("--plant", help="another FMU offering the plant contract")
    table3.add_argument("--out", help="output folder (default: out/table3)")
    table3.set_defaults(handler=_table3)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``twin`` console script."""
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except USER_ERRORS as exc:
        print(f"twin {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
