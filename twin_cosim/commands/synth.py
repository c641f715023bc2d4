"""``twin synth``: the virtual machine, a measured run with known effects (and its answer)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from twin_cosim.commands.console import warn_plant_mismatch, write_json
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    plant_option,
    plant_path,
    whole_number,
)
from twin_cosim.commands.synth_machine import add_machine_options, run_machine_synth

if TYPE_CHECKING:
    from twin_cosim.gap.synth import EffectSpec
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario

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


def add_arguments(subparsers) -> None:
    """The ``synth`` command and its options."""
    parser = command_parser(
        subparsers, "synth", "the virtual machine: a measured run with known effects", run
    )
    parser.epilog = EFFECTS_HELP
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="effect to switch on (repeatable); NAME from the plant model's library (listed "
        "below) or 'plant'; a machine scenario's names its axis first, AXIS:NAME:... "
        "(default: none)",
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


def _error_options(parser: argparse.ArgumentParser) -> None:
    """The calibration error and the measurement noise, and their seed."""
    parser.add_argument(
        "--perturb", type=float, default=0.0, help="calibration error, relative (e.g. 0.03)"
    )
    parser.add_argument(
        "--seed", type=whole_number(0), default=0, help="seed of the noise and perturbation"
    )
    parser.add_argument(
        "--noise-position", type=float, default=20e-9, help="white noise on x, m (RMS)"
    )
    parser.add_argument(
        "--noise-current", type=float, default=5e-3, help="white noise on the current, A (RMS)"
    )


def run(args: argparse.Namespace) -> int:
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
    from twin_cosim.scenario.plant_file import PlantParameters, write_plant_parameters

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
