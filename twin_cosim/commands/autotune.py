"""``twin autotune``: an FRF auto-tuner, the industrial baseline beside the optimizers."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin_cosim.commands.console import command_line, warn_plant_mismatch, write_json
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    fraction,
    number_above,
    out_folder,
    output_options,
    plant_option,
    plant_parameters_option,
    plant_path,
)


def add_arguments(subparsers) -> None:
    """The ``autotune`` command and its options."""
    parser = command_parser(
        subparsers,
        "autotune",
        "set Kp_vel, Ki_vel, a notch, Kp_pos and the feedforwards from the plant FRF",
        run,
    )
    parser.add_argument("scenario", help="scenario YAML file, or the name of a shipped one")
    parser.add_argument(
        "--frf",
        metavar="FRF.csv",
        help="the plant FRF of the machine (as twin calibrate reads it) (default: measured on "
        "the twin at an operating speed, nonlinearities on)",
    )
    parser.add_argument(
        "--phase-margin",
        type=number_above(0.0),
        default=50.0,
        help="the speed loop's phase-margin target, degrees",
    )
    parser.add_argument(
        "--coherence-floor",
        type=fraction(0.0, 1.0),
        default=0.8,
        help="lines of the FRF file of lower coherence are left out",
    )
    plant_option(parser)
    plant_parameters_option(parser)
    output_options(parser, "output folder (default: out/autotune-<scenario name>)")
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Tune, run the scenario with the set, write autotune.json (a controller set) and the plot."""
    from twin_cosim.frequency.autotune import autotune_scenario, plot_design
    from twin_cosim.scenario import resolve_scenario
    from twin_cosim.versions import versions

    scenario = resolve_scenario(args.scenario, args.plant_parameters, args.plant)
    mismatch = warn_plant_mismatch(scenario, plant_path(args))
    out = out_folder(args.out, Path("out") / f"autotune-{scenario.name}")
    proposal, ran = autotune_scenario(
        scenario,
        Path(args.frf) if args.frf else None,
        plant_path(args),
        args.phase_margin,
        args.coherence_floor,
    )
    out.mkdir(parents=True, exist_ok=True)
    summary = {
        **proposal.summary(),
        **ran,
        "scenario": str(scenario.source),
        "phase_margin_target_deg": args.phase_margin,
        "warnings": mismatch,
        "versions": versions(),
    }
    write_json(out / "autotune.json", summary)
    command = command_line("autotune")
    plot = plot_design(proposal, scenario, out / "speed_loop.png", command)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_text(summary, out, plot)
    return 0


def _print_text(summary: dict, out: Path, plot: Path) -> None:
    """The set, its margins and its metrics beside the scenario's own set's."""
    for note in summary["notes"]:
        print(f"twin autotune: {note}")
    print("params: " + ", ".join(f"{k}={v:.6g}" for k, v in summary["params"].items()))
    settings = summary["settings"]
    filters = settings["filters"] or "none"
    print(f"current filters: {filters}; feedforward inertia {settings['inertia']:.4g} kg.m2")
    for label, key in (("speed", "margins"), ("position", "position_margins")):
        m = summary[key]
        print(
            f"{label} loop: phase margin {m['phase_margin_deg']:.1f} deg at "
            f"{m['crossover_hz']:.1f} Hz, gain margin {m['gain_margin_db']:.1f} dB, "
            f"bandwidth {m['bandwidth_hz']:.1f} Hz"
        )
    new, own = summary["metrics"], summary["scenario_metrics"]
    print(
        f"E_pk {new['E_pk_um']:.3f} um (scenario's set {own['E_pk_um']:.3f} um), IAU "
        f"{new['IAU']:.4g} A.s ({own['IAU']:.4g}); {summary['wall_s']:.2f} s"
    )
    print(f"wrote {out / 'autotune.json'} (a controller set: --params, --start), {plot}")
