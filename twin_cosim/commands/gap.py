"""The sim-to-real gap's commands: ``twin synth`` makes a measured run with known effects,
``twin diagnose`` finds where the twin is wrong, why, and by how much.

- ``twin synth``: the virtual machine, a measured run with known effects (and its answer);
- ``twin synth MACHINE`` (a scenario with ``axes:``): a measured circular test or program run
  of a virtual machine. The circle (``--radius``, ``--feed``, ``--direction``) or the part
  program (``--program``, else the scenario's) runs on the machine with effects switched on per
  axis (``--effect AXIS:NAME:...``), calibration error and measurement noise, and its geometric
  errors (:func:`twin_cosim.contour.measured_circle.synthesize_motion`); the CSV is a measured
  test for ``twin circle MACHINE --measured RUN.csv``, and ``RUN.csv.truth.json`` holds the
  answer;
- ``twin diagnose``: the diagnosis of a measured run and the calibrated plant file.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim.commands.console import warn_plant_mismatch, write_json
from twin_cosim.commands.options import (
    column_map,
    columns_option,
    data_option,
    fraction,
    no_plots_option,
    number_options,
    out_folder,
    output_options,
    plant_option,
    plant_path,
    pool_options,
    quiet_option,
    scenario_parser,
    whole_number,
)

if TYPE_CHECKING:
    from twin_cosim.gap.diagnosis import Diagnosis
    from twin_cosim.gap.synth import EffectSpec
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario
    from twin_cosim.scenario.machine import MachineScenario
    from twin_cosim.workers import ProcessPool, SerialPool


# The effect libraries of the plant models (models/<model>/card.yaml; a test checks this text).
EFFECTS_HELP = """\
effects of each plant model (NAME: its parameters):
  drive2mass: stribeck (stribeck_friction, stribeck_speed), coulomb_change (delta_coulomb),
    asymmetric_friction (coulomb_asymmetry), position_friction (cos_part, sin_part),
    pitch_error (pitch_error_linear, cos_part, sin_part), torque_ripple (cos_part, sin_part),
    current_lag (current_time_constant), dead_time (dead_time_steps), quantization
    (position_resolution), backlash_change (delta_backlash), inertia_change (relative_change),
    stiffness_change (relative_change)
  emps: stribeck (stribeck_friction, stribeck_speed), coulomb_change (delta_coulomb),
    asymmetric_friction (coulomb_asymmetry, viscous_asymmetry), viscous_change (delta_viscous),
    offset_change (delta_offset), inertia_change (relative_change), compliance (mass_fraction,
    coupling_frequency), torque_ripple (cos_part, sin_part), dead_time (dead_time_steps)
  hsm150: coulomb_change (delta_coulomb), asymmetric_friction (coulomb_forward,
    coulomb_backward, viscous_forward, viscous_backward), stribeck (stribeck_friction,
    stribeck_speed), viscous_change (relative_change), inertia_change (relative_change),
    torque_constant_change (relative_change), torque_asymmetry (torque_asymmetry), dead_time
    (dead_time_steps)
  plant: any FMU parameter, e.g. plant:backlash=30e-6
units and ranges: models/<model>/README.md; e.g.
  --effect stribeck:stribeck_friction=0.2,stribeck_speed=0.5
"""


def add_synth(subparsers) -> None:
    """The ``synth`` command and its options."""
    parser = scenario_parser(
        subparsers, "synth", "the virtual machine: a measured run with known effects", run_synth
    )
    parser.epilog = EFFECTS_HELP
    effect_option(
        parser,
        "effect to switch on (repeatable); NAME from the plant model's library (listed below) or "
        "'plant'; a machine scenario's names its axis first, AXIS:NAME:... (default: none)",
    )
    _error_options(parser)
    plant_option(parser)
    parser.add_argument(
        "--follow",
        metavar="RUN",
        help="follow this measured run's reference and disturbance (a scenario whose reference "
        "comes from a measured file), e.g. a pulse template for an EMPS validation run "
        "(default: the scenario's own reference)",
    )
    parser.add_argument(
        "--random-excitation",
        type=whole_number(0),
        metavar="SEED",
        help="follow the seeded random excitation SEED instead of the scenario's reference "
        "(moves, creeps, ramps, oscillations and dwells, each half covering every regime; "
        "docs/gap.md) and write that scenario beside the run, RUN.scenario.yaml, for twin "
        "diagnose (default: the scenario's own reference)",
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="RUN",
        help="measured run to write, a new file: .csv, or .mat in the EMPS format (required)",
    )
    parser.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    add_machine_options(parser)
    data_option(parser)


ERROR_NUMBERS = (  # option, type, default, metavar, help
    ("--perturb", float, 0.0, None, "calibration error, relative (e.g. 0.03)"),
    ("--seed", whole_number(0), 0, None, "seed of the noise and perturbation"),
    ("--noise-position", float, 20e-9, None, "white noise on x, m (RMS)"),
    ("--noise-current", float, 5e-3, None, "white noise on the current, A (RMS)"),
)


def effect_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--effect NAME:param=value,...`` (repeatable; ``what``: its help)."""
    parser.add_argument(
        "--effect", action="append", default=[], metavar="NAME:param=value,...", help=what
    )


def _error_options(parser: argparse.ArgumentParser) -> None:
    """The calibration error and the measurement noise, and their seed."""
    number_options(parser, ERROR_NUMBERS)


def run_synth(args: argparse.Namespace) -> int:
    """Synthesize the run, write it, its known answer (``RUN.truth.json``) and the virtual
    machine's plant file (``RUN.machine.yaml``)."""
    from twin_cosim.gap.synth import synthesize, write_excitation_scenario
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import (
        find_scenario,
        for_measured_run,
        is_machine_scenario,
        resolve_scenario,
    )

    if is_machine_scenario(args.scenario):
        return run_machine_synth(args, _effect)
    if args.radius is not None or args.feed is not None or args.program:
        raise ValueError("--radius, --feed and --program: for a machine scenario (axes:)")
    out, truth, machine = _files(args)
    if args.random_excitation is not None:
        if args.follow:
            raise ValueError("--random-excitation and --follow: give one reference to follow")
        followed = write_excitation_scenario(
            find_scenario(args.scenario),
            args.random_excitation,
            out.with_name(out.name + ".scenario.yaml"),
        )
        scenario = resolve_scenario(followed)
    else:
        scenario = resolve_scenario(args.scenario)
    warn_plant_mismatch(scenario, plant_path(args))
    if args.follow:
        scenario = for_measured_run(scenario, read_measured(args.follow))
    effects = [_effect(text, None if args.plant else scenario.model) for text in args.effect]
    synthesis = synthesize(
        scenario,
        effects,
        args.perturb,
        args.seed,
        plant_path(args),
        args.noise_position,
        args.noise_current,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() == ".mat":
        _write_emps(out, synthesis.run, scenario, args.follow, args.plant)
    else:
        synthesis.run.frame().to_csv(out, index=False)
    write_json(truth, {**synthesis.truth, "followed": args.follow})
    wrote = _write_machine(machine, scenario, synthesis.truth, out, args.plant)
    print(
        f"wrote {out} ({len(synthesis.run)} samples), the known answer in {truth}"
        + (f", the virtual machine's plant in {machine} (twin simulate --machine)" if wrote else "")
        + (
            f" and the scenario it followed in {scenario.source} (twin diagnose)"
            if args.random_excitation is not None
            else ""
        )
    )
    return 0


def _write_machine(path: Path, scenario: Scenario, truth: dict, out: Path, fmu: str | None) -> bool:
    """The virtual machine as a plant file (``--machine`` of ``twin simulate``, docs/transfer.md):
    the scenario's plant parameters with those synth changed; False for an FMU (``--plant``)
    of no model of the project."""
    from twin_cosim.plant_model import model_names
    from twin_cosim.scenario.plant_parameters import PlantParameters, write_plant_parameters

    model = scenario.model_name(Path(fmu) if fmu else None)
    if model not in model_names():
        return False
    nominal = {k: v for k, v in scenario.plant_parameters.items() if k != "load_position_start"}
    created_by = {"command": "twin synth", "run": str(out), "effects": truth["effects"]}
    parameters = {**nominal, **truth["plant_parameters"]}
    write_plant_parameters(path, PlantParameters(model, parameters, created_by=created_by))
    return True


def _effect(text: str, model: str | None) -> EffectSpec:
    """The ``--effect`` of ``text``: an effect of ``model``'s library (None, an FMU given with
    ``--plant``: of any model's) or ``plant``."""
    from twin_cosim.gap.synth import parse_effect
    from twin_cosim.plant_model import plant_model

    name = text.partition(":")[0]
    if model is not None and name != "plant":
        known = [h.name for h in plant_model(model).hypotheses]
        if name not in known:
            raise ValueError(
                f"--effect {text!r}: {name!r} is not an effect of plant model {model!r}; "
                f"expected 'plant' or one of {', '.join(known)} (twin synth --help)"
            )
    return parse_effect(text)


def _files(args: argparse.Namespace) -> tuple[Path, Path, Path]:
    """The run to write, its answer file and its machine's plant file, refused when they exist
    (unless ``--force``)."""
    out = Path(args.out)
    truth = out.with_name(out.name + ".truth.json")
    machine = out.with_name(out.name + ".machine.yaml")
    followed = (
        [out.with_name(out.name + ".scenario.yaml")] if args.random_excitation is not None else []
    )
    if out.is_dir():
        raise ValueError(f"--out {out}: is a folder; give the measured-run file to write")
    if out.suffix.lower() not in (".csv", ".mat"):
        raise ValueError(f"--out {out}: expected a .csv or an EMPS .mat file name")
    for path in (out, truth, machine, *followed):
        if path.exists() and not args.force:
            raise ValueError(
                f"--out {out}: {path} exists (it may be a real measured run); "
                "give another --out, or --force to overwrite"
            )
    return out, truth, machine


def _write_emps(
    out: Path, run: RunRecord, scenario: Scenario, follow: str | None, fmu: str | None
) -> None:
    """Write the run as an EMPS .mat file, with the followed run's pulses when it has them."""
    import numpy as np

    from twin_cosim.emps_runs import emps_gains, write_emps_mat
    from twin_cosim.measured import read_measured

    pulses = None
    if follow and scenario.disturbance_spec:
        followed = read_measured(follow)
        values = followed.record.get(scenario.disturbance_spec["variable"])
        if isinstance(values, np.ndarray):
            pulses = np.interp(run["t"], followed.t, values)
    gains = emps_gains(scenario, follow, fmu)
    write_emps_mat(out, run["t"], run["x_ref"], run["x"], run["current"], gains, pulses)


_SINGLE_AXIS_OPTIONS = ("plant", "follow")


def add_machine_options(parser: argparse.ArgumentParser) -> None:
    """The options of a machine's virtual run: the circle or the program."""
    parser.add_argument(
        "--radius",
        type=float,
        metavar="MM",
        help="machine scenarios: a circular test of this radius, mm (with --feed) "
        "(default: none, the program)",
    )
    parser.add_argument(
        "--feed",
        type=float,
        metavar="MM_PER_MIN",
        help="machine scenarios: the circle's feed, mm/min (with --radius) (default: none)",
    )
    parser.add_argument(
        "--direction",
        choices=["cw", "ccw"],
        default="ccw",
        help="machine scenarios: the circle's direction (default: ccw)",
    )
    parser.add_argument(
        "--program",
        metavar="PART.nc",
        help="machine scenarios: run this part program (default without --radius: the "
        "scenario's program)",
    )


def run_machine_synth(
    args: argparse.Namespace, library_effect: Callable[[str, str], EffectSpec]
) -> int:
    """Synthesize the machine's run, write it and its known answer (``RUN.truth.json``);
    ``library_effect(text, model)`` reads an ``--effect`` of a plant model's library (the one
    of ``twin synth`` for one axis)."""
    from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, circle_motion
    from twin_cosim.contour.gcode import read_program
    from twin_cosim.contour.machine_run import plan_on
    from twin_cosim.contour.measured_circle import synthesize_motion
    from twin_cosim.scenario import load_machine

    for option in _SINGLE_AXIS_OPTIONS:
        if getattr(args, option, None):
            raise ValueError(f"--{option}: for a single-axis scenario, not a machine (axes:)")
    out, truth = _machine_files(args)
    machine = load_machine(args.scenario)
    effects = _axis_effects(args.effect, machine, library_effect)
    if args.radius is not None or args.feed is not None:
        if args.radius is None or args.feed is None or args.program:
            raise ValueError("a circle takes --radius MM and --feed MM_PER_MIN (not --program)")
        spec = CircleSpec(args.radius * 1e-3, args.feed * MM_PER_MIN, args.direction)
        motion, _ = circle_motion(machine, spec)
        ran = {"circle": {"radius_mm": args.radius, "feed_mm_min": args.feed}}
        ran["circle"]["direction"] = args.direction
    else:
        source = Path(args.program) if args.program else machine.program
        if source is None:
            raise ValueError(f"{machine.source}: no program: give --program or --radius/--feed")
        motion = plan_on(machine, read_program(source, machine.axis_names))
        ran = {"program": str(source)}
    run = synthesize_motion(
        machine, motion, effects, args.perturb, args.seed, args.noise_position, args.noise_current
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    run.frame().to_csv(out, index=False)
    write_json(
        truth,
        {
            "scenario": str(machine.source),
            **ran,
            "effects": {axis: [_effect_truth(e) for e in found] for axis, found in effects.items()},
            "geometry": machine.geometry.as_dict(),
            "perturb": args.perturb,
            "seed": args.seed,
            "noise_position_m": args.noise_position,
            "noise_current_A": args.noise_current,
        },
    )
    print(f"wrote {out} ({len(run)} samples) and the known answer in {truth}")
    return 0


def _effect_truth(effect: EffectSpec) -> dict:
    """An effect as the answer file holds it."""
    return {"name": effect.name, "params": dict(effect.params)}


def _axis_effects(
    texts: list[str], machine: MachineScenario, library_effect: Callable[[str, str], EffectSpec]
) -> dict[str, list[EffectSpec]]:
    """``--effect AXIS:NAME:param=value,...`` of a machine: each effect in its axis' plant
    model's library (or ``plant``)."""
    effects: dict[str, list[EffectSpec]] = {}
    for text in texts:
        axis, _, effect = text.partition(":")
        if axis not in machine.axis_names or not effect:
            raise ValueError(
                f"--effect {text!r}: a machine's effect names its axis first, one of "
                f"{list(machine.axis_names)}, e.g. Y:stribeck:stribeck_friction=0.3"
            )
        model = machine.axis(axis).model_name()
        effects.setdefault(axis, []).append(library_effect(effect, model))
    return effects


def _machine_files(args: argparse.Namespace) -> tuple[Path, Path]:
    """The run to write (a new .csv) and its answer file, refused when they exist (unless
    ``--force``)."""
    out = Path(args.out)
    truth = out.with_name(out.name + ".truth.json")
    if out.is_dir():
        raise ValueError(f"--out {out}: is a folder; give the measured-run file to write")
    if out.suffix.lower() != ".csv":
        raise ValueError(f"--out {out}: expected a .csv file name (a machine's measured run)")
    for path in (out, truth):
        if path.exists() and not args.force:
            raise ValueError(
                f"--out {out}: {path} exists (it may be a real measured run); "
                "give another --out, or --force to overwrite"
            )
    return out, truth


def add_diagnose(subparsers) -> None:
    """The ``diagnose`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "diagnose",
        "where the twin is wrong, why, and by how much",
        run_diagnose,
        "scenario YAML file (or shipped name) the runs followed",
    )
    parser.add_argument(
        "--measured",
        action="append",
        required=True,
        help="measured run: CSV (units in its header, TwinCAT Scope export), EMPS or HSM150 "
        ".mat (repeatable; required, no default)",
    )
    parser.add_argument(
        "--holdout", action="append", help="held-out run(s) (default: a time split)"
    )
    columns_option(parser)
    parser.add_argument(
        "--split",
        type=fraction(0.1, 0.9),
        help="training fraction of the time split "
        "(default: the scenario's diagnose.split, else 0.5)",
    )
    parser.add_argument(
        "--max-effects",
        type=whole_number(1),
        help="effects to accept at most (default: the scenario's diagnose.max_effects, else 3)",
    )
    plant_option(parser)
    pool_options(parser, "local processes for the fits (default: all cores)")
    output_options(parser, "report folder (default: out/diagnosis-<scenario name>)")
    quiet_option(
        parser, "no progress bar (there is none either with --json when stdout is not a terminal)"
    )
    no_plots_option(parser)
    data_option(parser)


def run_diagnose(args: argparse.Namespace) -> int:
    """Diagnose, write the report, plant.yaml and calibrated.yaml, print the verdict, then draw
    the report's figures.

    The replay pool's processes start first, so that they load the co-simulation while this
    process reads the runs and replays the nominal twin.
    """
    from twin_cosim.workers import make_pool, prepare_replay_worker

    with make_pool(None, args.workers, prepare_replay_worker) as pool:
        return _run_on(args, pool)


def _run_on(args: argparse.Namespace, pool: SerialPool | ProcessPool) -> int:
    """The diagnosis, its files and its figures, with ``pool`` running the replays."""
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.gap.report.pages import summary as summary_of
    from twin_cosim.gap.report.pages import write_report
    from twin_cosim.gap.settings import settings_from
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import resolve_scenario
    from twin_cosim.versions import versions

    scenario = resolve_scenario(args.scenario)
    mismatch = warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / f"diagnosis-{scenario.name}")
    columns, open_loop = column_map(args, scenario), scenario.drive is not None
    measured = [read_measured(path, columns, open_loop) for path in args.measured]
    holdout = [read_measured(path, columns, open_loop) for path in args.holdout or []]
    settings = settings_from(scenario, args.split, args.max_effects)
    start = time.perf_counter()
    progress = _ProgressBars(args)
    try:
        result = diagnose(
            scenario, measured, holdout, args.plant, settings, progress=progress, pool=pool
        )
    finally:
        progress.finish()
    wall_s = time.perf_counter() - start
    summary = {
        **summary_of(result),
        "wall_s": wall_s,
        "versions": versions(),
        "warnings": mismatch + result.warnings,
    }
    files = write_report(result, out, summary, _command(args), figures=not args.no_plots)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_text(result)
    if not args.no_plots:
        from twin_cosim.gap.report.figures import write_figures

        write_figures(result, out)
    if not args.json:
        print(
            f"wrote {files['markdown']}, {files['html']}, {files['json']}, {files['plant']}, "
            f"{files['calibrated']}{'' if args.no_plots else ' and figures'} ({wall_s:.1f} s)"
        )
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command that made the diagnosis, as plant.yaml records it."""
    runs = [f"--measured {m}" for m in args.measured]
    runs += [f"--holdout {h}" for h in args.holdout or []]
    return " ".join(["twin diagnose", str(args.scenario), *runs])


class _ProgressBars:
    """tqdm progress bars on stderr, one per ``make(total, label)``; none with ``--quiet``, or
    with ``--json`` when stdout is not a terminal. A bar's total is the most tasks the work may
    take; :meth:`finish` closes each bar at 100 % of what it did."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.enabled = not args.quiet and not (args.json and not sys.stdout.isatty())
        self.bars: list[Any] = []

    def __call__(self, total: int, label: str) -> Callable[[int], None]:
        from tqdm import tqdm

        bar = tqdm(total=total, desc=label, unit="task", disable=not self.enabled, file=sys.stderr)
        self.bars.append(bar)

        def tick(done: int) -> None:
            if bar.n + done > bar.total:
                bar.total = bar.n + done
            bar.update(done)

        return tick

    def finish(self) -> None:
        """Close every bar, its total set to the tasks done (the work ended early)."""
        for bar in self.bars:
            bar.total = bar.n
            bar.close()
        self.bars = []


def _print_text(result: Diagnosis) -> None:
    """The verdict and each accepted effect's held-out gaps, numbers for people."""
    from twin_cosim.gap.report.pages import hypothesis_units
    from twin_cosim.gap.verdict import names, number, parameters
    from twin_cosim.measured import compared_label

    units = hypothesis_units(result.context.model)
    words, unit = compared_label(result.context.compared)
    x = result.context.position_label
    print(result.verdict)
    for step in result.steps:
        best = step.best
        assert best is not None
        print(
            f"  {names([step.effect])}: held-out {x.words} gap "
            f"{number(step.position_rms_um * x.per_um)} -> "
            f"{number(best.judgement.position_rms_um * x.per_um)} "
            f"{x.unit}, {words} {number(step.current_rms)} -> "
            f"{number(best.judgement.current_rms)} {unit}, as fitted in its round: "
            f"{parameters(best.fit.values, units.get(best.name, {}))}"
        )
