"""The ``twin`` command line: build, simulate, optimize, compare.

Only the standard library and the light registries are imported at start, so that ``twin
--help`` answers at once; each command imports what it needs (numpy, pandas, fmpy, numba,
matplotlib) when it runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fmu_build.build import CACHE_ENV, DEFAULT_MODEL, available_models
from twin_cosim.environment import DATA_ENV
from twin_cosim.optimize.methods import METHOD_NAMES, method_list

if TYPE_CHECKING:
    from twin_cosim.scenario import Scenario


def user_errors() -> tuple[type[Exception], ...]:
    """The exceptions that are the user's mistakes: a message and exit status 2."""
    from fmu_build.build import BuildError
    from fmu_build.variable_table import VariableTableError
    from twin_cosim.plant import PlantError
    from twin_cosim.reference import ReferenceError
    from twin_cosim.scenario import ScenarioError

    return (
        BuildError,
        VariableTableError,
        PlantError,
        ScenarioError,
        ReferenceError,
        ValueError,
        OSError,  # a file or folder that cannot be read or written; the message names it
    )


def warn_plant_mismatch(scenario: Scenario, fmu: Path | None) -> list[str]:
    """Warn on stderr when ``--plant`` is another model than the scenario's; the warnings."""
    from twin_cosim.scenario import plant_mismatch

    warning = None if fmu is None else plant_mismatch(scenario, fmu)
    if warning is None:
        return []
    print(f"twin: warning: {warning}", file=sys.stderr)
    return [warning]


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2) + "\n")


def whole_number(low: int):
    """An argparse type: a whole number >= ``low`` (the message names the option)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text!r}")
        return value

    return parse


def fraction(low: float, high: float):
    """An argparse type: a number in [low, high]."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a number in [{low}, {high}], got {text!r}")
        return value

    return parse


def out_folder(option: str | None, default: Path) -> Path:
    """The output folder of ``--out`` (or ``default``); an existing file is refused."""
    out = Path(option) if option else default
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder; give a folder")
    return out


def _build(args: argparse.Namespace) -> int:
    from fmu_build.build import build_fmu

    path = build_fmu(args.model, Path(args.out) if args.out else None, force=args.force)
    print(path)
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from twin_cosim.cosim import run_scenario
    from twin_cosim.metrics import compute_metrics
    from twin_cosim.plant import Plant
    from twin_cosim.plant_parameters import with_plant_parameters
    from twin_cosim.plots import plot_run
    from twin_cosim.run_checks import loop_warnings
    from twin_cosim.scenario import load_scenario, load_tuned_parameters
    from twin_cosim.versions import versions

    scenario = with_plant_parameters(
        load_scenario(args.scenario), args.plant_parameters, args.plant
    )
    tuned = load_tuned_parameters(args.params) if args.params else scenario.tuned
    fmu = Path(args.plant) if args.plant else scenario.fmu
    mismatch = warn_plant_mismatch(scenario, Path(args.plant) if args.plant else None)
    out = out_folder(args.out, Path("out") / scenario.name)
    out.mkdir(parents=True, exist_ok=True)
    with Plant(fmu) as plant:
        start = time.perf_counter()
        record = run_scenario(plant, scenario, tuned, fast=not args.reference_path)
        wall = time.perf_counter() - start
        fmu_path = str(plant.fmu_path)
    metrics = compute_metrics(record, scenario.metrics_window)
    diverged, loop = loop_warnings(record, scenario)
    warnings = mismatch + loop
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
        "warnings": warnings,
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
    for warning in warnings:
        print(f"twin simulate: warning: {warning}", file=sys.stderr)
    return 1 if diverged else 0


def _table3(args: argparse.Namespace) -> int:
    from twin_cosim import paper
    from twin_cosim.metrics import compute_metrics
    from twin_cosim.plant import Plant
    from twin_cosim.plots import plot_error_comparison
    from twin_cosim.report import evaluate_sets, markdown_table
    from twin_cosim.scenario import load_scenario

    scenarios = {str(path): load_scenario(path) for path in args.scenarios}
    for scenario in scenarios.values():
        warn_plant_mismatch(scenario, Path(args.plant) if args.plant else None)
    out = out_folder(args.out, Path("out") / "table3")
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
    from twin_cosim.optimize.campaign import run_campaign
    from twin_cosim.optimize.campaign_folder import load_spec
    from twin_cosim.optimize.campaign_spec import CampaignSpec
    from twin_cosim.optimize.cases import campaign_scenarios
    from twin_cosim.optimize.outputs import write_campaign_plots

    given = _given_options(args)
    if args.resume:  # the campaign refuses options that differ from the stored ones
        stored = load_spec(Path(args.resume))
        fmu = args.plant or stored.fmu
        spec = dataclasses.replace(stored, scenario=args.scenario[0], fmu=fmu, **given)
        out = Path(args.resume)
    else:
        if args.method is None:
            raise ValueError(f"--method is required ({method_list()}) unless --resume is given")
        spec = CampaignSpec(scenario=args.scenario[0], fmu=args.plant, **given)
        out = out_folder(args.out, Path("out") / f"optimize-{spec.method}-seed{spec.seed}")
    scenarios = campaign_scenarios(spec)
    if not args.resume:
        warn_plant_mismatch(scenarios[0], Path(args.plant) if args.plant else None)
    try:
        result = run_campaign(
            spec,
            out,
            workers=args.workers,
            scheduler=args.scheduler,
            resume=bool(args.resume),
            progress=not args.quiet,
            scenarios=scenarios,
        )
    except KeyboardInterrupt as exc:
        if (out / "campaign.json").exists():
            scenarios = " ".join(args.scenario)
            exc.hint = f"; the log is intact: twin optimize {scenarios} --resume {out}"
        raise
    write_campaign_plots(out, spec, scenarios[0])
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


def _given_options(args: argparse.Namespace) -> dict[str, Any]:
    """The campaign options given on the command line (those not given are left out)."""
    given = {
        "method": args.method,
        "seed": args.seed,
        "budget": args.budget,
        "plant_parameters": args.plant_parameters,
        "scenarios": list(args.scenario[1:]) or None,
        "tolerance": args.tolerance,
        "samples": args.samples,
        "aggregate": args.objective,
        "relative": True if args.relative else None,
        "early_stop": False if args.no_early_stop else None,
    }
    return {k: v for k, v in given.items() if v is not None}


def _compare(args: argparse.Namespace) -> int:
    from twin_cosim.optimize.comparison import load_comparison, run_comparison

    comparison = load_comparison(Path(args.campaign))
    if args.plant_parameters:
        comparison = dataclasses.replace(comparison, plant_parameters=Path(args.plant_parameters))
    methods = args.methods.split(",") if args.methods else None
    out = out_folder(args.out, Path("out") / comparison.name)
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
    import numpy as np

    from twin_cosim.emps_runs import emps_gains, write_emps_mat
    from twin_cosim.gap.synth import parse_effect, synthesize
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import for_measured_run, load_scenario

    out = Path(args.out)
    truth = out.with_name(out.name + ".truth.json")
    if out.is_dir():
        raise ValueError(f"--out {out}: is a folder; give the measured-run file to write")
    if out.suffix.lower() not in (".csv", ".mat"):
        raise ValueError(f"--out {out}: expected a .csv or an EMPS .mat file name")
    for path in (out, truth):
        if path.exists() and not args.force:
            raise ValueError(
                f"--out {out}: {path} exists (it may be a real measured run); "
                "give another --out, or --force to overwrite"
            )
    scenario = load_scenario(args.scenario)
    warn_plant_mismatch(scenario, Path(args.plant) if args.plant else None)
    if args.follow:
        scenario = for_measured_run(scenario, read_measured(args.follow))
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
    out.parent.mkdir(parents=True, exist_ok=True)
    run = synthesis.run
    if out.suffix.lower() == ".mat":
        pulses = None
        if args.follow and scenario.disturbance_spec:
            followed = read_measured(args.follow)
            values = followed.extra.get(scenario.disturbance_spec["variable"])
            if isinstance(values, np.ndarray):
                pulses = np.interp(run["t"], followed.t, values)
        gains = emps_gains(scenario, args.follow, args.plant)
        write_emps_mat(out, run["t"], run["x_ref"], run["x"], run["current"], gains, pulses)
    else:
        run.to_csv(out, index=False)
    write_json(truth, {**synthesis.truth, "followed": args.follow})
    print(f"wrote {out} ({len(run)} samples) and the known answer in {truth}")
    return 0


def _progress_bar(enabled: bool):
    """A factory of tqdm progress bars on stderr (none when disabled)."""
    from tqdm import tqdm

    def make(total: int, label: str):
        bar = tqdm(total=total, desc=label, unit="task", disable=not enabled, file=sys.stderr)

        def tick(done: int) -> None:
            if bar.n + done > bar.total:
                bar.total = bar.n + done
            bar.update(done)

        return tick

    return make


def _diagnose(args: argparse.Namespace) -> int:
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.gap.plant_file import write_calibration
    from twin_cosim.gap.report import write_report
    from twin_cosim.gap.settings import settings_from
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import load_scenario
    from twin_cosim.versions import versions

    scenario = load_scenario(args.scenario)
    mismatch = warn_plant_mismatch(scenario, Path(args.plant) if args.plant else None)
    out = out_folder(args.out, Path("out") / f"diagnosis-{scenario.name}")
    measured = [read_measured(path) for path in args.measured]
    holdout = [read_measured(path) for path in args.holdout or []]
    settings = settings_from(scenario, args.split, args.max_effects)
    start = time.perf_counter()
    show = not args.quiet and not (args.json and not sys.stdout.isatty())
    result = diagnose(
        scenario,
        measured,
        holdout,
        args.plant,
        settings,
        workers=args.workers,
        progress=_progress_bar(show),
    )
    extra = {
        "wall_s": time.perf_counter() - start,
        "versions": versions(),
        "warnings": mismatch + result.summary()["warnings"],
    }
    files = write_report(result, out, extra)
    summary = {**result.summary(), **extra}
    runs = [f"--measured {m}" for m in args.measured]
    runs += [f"--holdout {h}" for h in args.holdout or []]
    command = " ".join(["twin diagnose", str(args.scenario), *runs])
    files |= write_calibration(scenario, summary, out, command, args.plant)
    if args.json:
        print(json.dumps(summary))
    else:
        print(summary["gap"]["verdict"])
        for step in summary["steps"]:
            print(
                f"  {step['effect']}: held-out position gap {step['holdout_gap_before_um']:.3f} -> "
                f"{step['holdout_gap_after_um']:.3f} um, current "
                f"{step['holdout_current_before_A']:.4f} -> "
                f"{step['holdout_current_after_A']:.4f} A; fitted {step['params']}"
            )
        print(
            f"wrote {files['markdown']}, {files['html']}, {files['json']}, {files['plant']}, "
            f"{files['calibrated']} ({extra['wall_s']:.1f} s)"
        )
    return 0


class HelpFormatter(argparse.HelpFormatter):
    """Help that shows every option's default: the value, or what the help text says it is."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, argparse.SUPPRESS):
            return text
        if action.default is False:
            return f"{text} (default: off)"
        return f"{text} (default: %(default)s)"


def _data_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--data",
        metavar="DIR",
        help=f"folder of measured data files, e.g. the EMPS benchmark's DATA_EMPS.mat "
        f"(default: ${DATA_ENV}, else the path in the scenario)",
    )


def _plant_parameters_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--plant-parameters",
        metavar="FILE",
        help="calibrated plant parameters for every scenario, the plant.yaml of twin diagnose "
        "(default: none)",
    )


def _plant_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--plant",
        metavar="FMU",
        help="another FMU offering the plant contract (default: the scenario's plant)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``twin``."""
    parser = argparse.ArgumentParser(
        prog="twin", description="Digital twin of a CNC feed axis", formatter_class=HelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True)

    def command(name: str, help: str) -> argparse.ArgumentParser:
        return commands.add_parser(name, help=help, formatter_class=HelpFormatter)

    build = command("build", "build a plant FMU from models/<MODEL>")
    build.add_argument(
        "model", nargs="?", default=DEFAULT_MODEL, help=f"one of {available_models()}"
    )
    build.add_argument(
        "--out",
        metavar="DIR",
        help=f"output folder (default: the per-user cache, ${CACHE_ENV} or "
        "$XDG_CACHE_HOME/twin-cosim, one folder per source version)",
    )
    build.add_argument("--force", action="store_true", help="rebuild even if up to date")
    build.set_defaults(handler=_build)

    simulate = command("simulate", "run a scenario in closed loop")
    simulate.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    simulate.add_argument(
        "--params",
        help="ft|ga|ce|sa (paper Table 3) or a YAML/JSON file (default: the scenario's)",
    )
    _plant_option(simulate)
    _plant_parameters_option(simulate)
    simulate.add_argument(
        "--machine",
        metavar="RUN_OR_PLANT",
        help="judge on a machine: a measured run (CSV/.mat) made with these gains, or a virtual "
        "machine (a scenario or plant.yaml whose plant stands for the machine) (default: none)",
    )
    simulate.add_argument(
        "--out", metavar="DIR", help="output folder (default: out/<scenario name>)"
    )
    simulate.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object"
    )
    simulate.add_argument(
        "--reference-path",
        action="store_true",
        help="step through fmpy in plain Python instead of the compiled loop",
    )
    _data_option(simulate)
    simulate.set_defaults(handler=_simulate)

    optimize = command("optimize", "tune K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H]")
    optimize.add_argument(
        "scenario",
        nargs="+",
        help="scenario YAML file or shipped name (its optimize section); more scenarios: a "
        "robust objective over all of them",
    )
    optimize.add_argument(
        "--method", choices=METHOD_NAMES, help="optimizer (default: none; required unless --resume)"
    )
    optimize.add_argument("--seed", type=whole_number(0), help="seed (default: 0)")
    optimize.add_argument(
        "--budget", type=whole_number(1), help="maximum evaluations (default: the method's)"
    )
    optimize.add_argument(
        "--workers", type=whole_number(1), help="local processes (default: all cores; 1: serial)"
    )
    optimize.add_argument(
        "--scheduler",
        metavar="ADDR",
        help="Dask scheduler address, e.g. tcp://host:8786 (default: none, a local pool)",
    )
    _plant_option(optimize)
    optimize.add_argument(
        "--out", metavar="DIR", help="campaign folder (default: out/optimize-<method>-seed<N>)"
    )
    optimize.add_argument(
        "--resume", metavar="DIR", help="campaign folder to resume (default: a new campaign)"
    )
    _plant_parameters_option(optimize)
    optimize.add_argument(
        "--tolerance",
        type=float,
        help="relative tolerance of the uncertain plant parameters (default: 0, no samples)",
    )
    optimize.add_argument(
        "--samples",
        type=whole_number(1),
        help="plant samples per scenario, the first nominal (default: 1)",
    )
    optimize.add_argument(
        "--objective",
        choices=["worst", "mean"],
        help="over scenarios x samples (default: worst)",
    )
    optimize.add_argument(
        "--relative",
        action="store_true",
        help="score each run's E_pk relative to the reference set's (Fine-Tune) on the same "
        "scenario and plant sample, so that no scenario outweighs the others by being harder "
        "(default: off, E_pk in um)",
    )
    optimize.add_argument(
        "--no-early-stop",
        action="store_true",
        help="run every candidate to the end (early stopping is exact; this is for measuring it)",
    )
    optimize.add_argument("--json", action="store_true", help="print the result as one JSON object")
    optimize.add_argument("--quiet", action="store_true", help="no progress bar")
    _data_option(optimize)
    optimize.set_defaults(handler=_optimize)

    compare = command("compare", "several methods on one campaign file: Tables 3-5")
    compare.add_argument("campaign", help="campaign YAML file (see scenarios/paper_campaign.yaml)")
    compare.add_argument(
        "--methods",
        help="comma-separated subset of the campaign's methods (default: all of them)",
    )
    compare.add_argument(
        "--workers", type=whole_number(1), help="local processes (default: all cores)"
    )
    compare.add_argument(
        "--scheduler", metavar="ADDR", help="Dask scheduler address (default: none, a local pool)"
    )
    compare.add_argument(
        "--out", metavar="DIR", help="output folder (default: out/<campaign name>)"
    )
    _plant_parameters_option(compare)
    compare.add_argument("--quiet", action="store_true", help="no progress bars")
    _data_option(compare)
    compare.set_defaults(handler=_compare)

    synth = command("synth", "the virtual machine: a measured run with known effects")
    synth.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    synth.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="effect to switch on (repeatable); NAME from the library or 'plant' (default: none)",
    )
    synth.add_argument(
        "--perturb", type=float, default=0.0, help="calibration error, relative (e.g. 0.03)"
    )
    synth.add_argument(
        "--seed", type=whole_number(0), default=0, help="seed of the noise and perturbation"
    )
    synth.add_argument(
        "--noise-position", type=float, default=20e-9, help="white noise on x, m (RMS)"
    )
    synth.add_argument(
        "--noise-current", type=float, default=5e-3, help="white noise on the current, A (RMS)"
    )
    _plant_option(synth)
    synth.add_argument(
        "--follow",
        metavar="RUN",
        help="follow this measured run's reference and disturbance (a scenario whose reference "
        "comes from a measured file), e.g. a pulse template for an EMPS validation run "
        "(default: the scenario's own reference)",
    )
    synth.add_argument(
        "--out",
        required=True,
        metavar="RUN",
        help="measured run to write, a new file: .csv, or .mat in the EMPS format (required)",
    )
    synth.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    _data_option(synth)
    synth.set_defaults(handler=_synth)

    diag = command("diagnose", "where the twin is wrong, why, and by how much")
    diag.add_argument("scenario", help="scenario YAML file (or shipped name) the runs followed")
    diag.add_argument(
        "--measured",
        action="append",
        required=True,
        help="measured run, CSV or EMPS .mat (repeatable; required, no default)",
    )
    diag.add_argument("--holdout", action="append", help="held-out run(s) (default: a time split)")
    diag.add_argument(
        "--split",
        type=fraction(0.1, 0.9),
        help="training fraction of the time split "
        "(default: the scenario's diagnose.split, else 0.5)",
    )
    diag.add_argument(
        "--max-effects",
        type=whole_number(1),
        help="effects to accept at most (default: the scenario's diagnose.max_effects, else 3)",
    )
    _plant_option(diag)
    diag.add_argument(
        "--workers", type=whole_number(1), help="local processes for the fits (default: all cores)"
    )
    diag.add_argument(
        "--out", metavar="DIR", help="report folder (default: out/diagnosis-<scenario name>)"
    )
    diag.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    diag.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (there is none either with --json when stdout is not a terminal)",
    )
    _data_option(diag)
    diag.set_defaults(handler=_diagnose)

    table3 = command("table3", "run the paper's Table 3 parameter sets on scenarios")
    table3.add_argument("scenarios", nargs="+", help="scenario YAML files or shipped names")
    _plant_option(table3)
    table3.add_argument("--out", metavar="DIR", help="output folder (default: out/table3)")
    _data_option(table3)
    table3.set_defaults(handler=_table3)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``twin`` console script.

    Exit status: 0 done; 1 done, but the result needs attention (``simulate``: the loop
    diverged); 2 a user error (bad file, key or option), with a message naming it; 128 + N ended
    by signal N (130 Ctrl-C, 143 SIGTERM), after a clean shutdown.
    """
    args = build_parser().parse_args(argv)
    if getattr(args, "data", None):
        os.environ[DATA_ENV] = args.data  # also seen by worker processes
    from twin_cosim.workers import command_temp_folder, terminate_as_interrupt

    terminate_as_interrupt()
    try:
        with command_temp_folder():
            return args.handler(args)
    except user_errors() as exc:
        print(f"twin {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        hint = getattr(exc, "hint", "")
        print(f"twin {args.command}: interrupted{hint}", file=sys.stderr)
        from twin_cosim.workers import Terminated

        return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)


if __name__ == "__main__":
    sys.exit(main())
