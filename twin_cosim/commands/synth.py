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

if TYPE_CHECKING:
    import pandas as pd

    from twin_cosim.scenario import Scenario


def add_arguments(subparsers) -> None:
    """The ``synth`` command and its options."""
    parser = command_parser(
        subparsers, "synth", "the virtual machine: a measured run with known effects"
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="effect to switch on (repeatable); NAME from the library or 'plant' (default: none)",
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
        "--out",
        required=True,
        metavar="RUN",
        help="measured run to write, a new file: .csv, or .mat in the EMPS format (required)",
    )
    parser.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    data_option(parser)
    parser.set_defaults(handler=run)


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
    """Synthesize the run, write it and its known answer (``RUN.truth.json``)."""
    from twin_cosim.gap.synth import parse_effect, synthesize
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import for_measured_run, resolve_scenario

    out, truth = _files(args)
    scenario = resolve_scenario(args.scenario)
    warn_plant_mismatch(scenario, plant_path(args))
    if args.follow:
        scenario = for_measured_run(scenario, read_measured(args.follow))
    effects = [parse_effect(text) for text in args.effect]
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
        synthesis.run.to_csv(out, index=False)
    write_json(truth, {**synthesis.truth, "followed": args.follow})
    print(f"wrote {out} ({len(synthesis.run)} samples) and the known answer in {truth}")
    return 0


def _files(args: argparse.Namespace) -> tuple[Path, Path]:
    """The run to write and its answer file, refused when they exist (unless ``--force``)."""
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
    return out, truth


def _write_emps(
    out: Path, run: pd.DataFrame, scenario: Scenario, follow: str | None, fmu: str | None
) -> None:
    """Write the run as an EMPS .mat file, with the followed run's pulses when it has them."""
    import numpy as np

    from twin_cosim.emps_runs import emps_gains, write_emps_mat
    from twin_cosim.measured import read_measured

    pulses = None
    if follow and scenario.disturbance_spec:
        followed = read_measured(follow)
        values = followed.extra.get(scenario.disturbance_spec["variable"])
        if isinstance(values, np.ndarray):
            pulses = np.interp(run["t"], followed.t, values)
    gains = emps_gains(scenario, follow, fmu)
    write_emps_mat(out, run["t"], run["x_ref"], run["x"], run["current"], gains, pulses)
