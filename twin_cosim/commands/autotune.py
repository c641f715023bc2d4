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
    no_plots_option,
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
        help="the speed loop's phase-margin target, degrees: the integral time is set so that "
        "the loop has it (within 0.5 deg), or the command says why none can",
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
    no_plots_option(parser)
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
        "warnings": mismatch,
        "versions": versions(),
    }
    write_json(out / "autotune.json", summary)
    command = command_line("autotune")
    plot = None
    if not args.no_plots:
        plot = plot_design(proposal, scenario, out / "speed_loop.png", command)
    if args.json:
        print(json.dumps(summary))
    else:
        _print_text(summary, out, plot)
    return 0


def _filter_text(section: dict) -> str:
    """A current filter as a drive shows it: notch at Hz, width Hz, depth dB; low-pass at Hz,
    damping."""
    if section["type"] == "notch":
        return (
            f"notch at {section['frequency_hz']:.4g} Hz, {section['bandwidth_hz']:.3g} Hz wide, "
            f"{section['depth_db']:.3g} dB"
        )
    return f"low-pass at {section['frequency_hz']:.4g} Hz, damping {section['damping']:.3g}"


def _print_text(summary: dict, out: Path, plot: Path | None) -> None:
    """The set, its loops' margins and closed-loop figures, and its metrics beside the
    scenario's own set's."""
    from twin_cosim.frequency.bode import margins_text
    from twin_cosim.frequency.margins import Margins

    for note in summary["notes"]:
        print(f"twin autotune: {note}")
    print("params: " + ", ".join(f"{k}={v:.6g}" for k, v in summary["params"].items()))
    settings = summary["settings"]
    filters = "; ".join(_filter_text(f) for f in settings["filters"]) or "none"
    print(f"current filters: {filters}; feedforward inertia {settings['inertia']:.4g} kg.m2")
    speed = Margins(**summary["margins"])
    position = Margins(**summary["position_margins"])
    print(
        f"speed loop: {margins_text(speed)} (target phase margin "
        f"{summary['phase_margin_target_deg']:g} deg)"
    )
    print(f"position loop: {margins_text(position)}")
    print(f"Kp_pos limited by the position loop's {summary['position_gain_limited_by']}")
    if (position.bandwidth_hz or 0.0) > (speed.bandwidth_hz or float("inf")):
        print(
            f"twin autotune: note: the position loop's bandwidth ({position.bandwidth_hz:.3g} Hz) "
            f"lies above the speed loop's ({speed.bandwidth_hz:.3g} Hz)"
        )
    new, own = summary["metrics"], summary["scenario_metrics"]
    print(
        f"E_pk {new['E_pk_um']:.3f} um (scenario's set {own['E_pk_um']:.3f} um), IAU "
        f"{new['IAU']:.4g} A.s ({own['IAU']:.4g}); {summary['wall_s']:.2f} s"
    )
    plotted = "" if plot is None else f", {plot}"
    print(f"wrote {out / 'autotune.json'} (a controller set: --params, --start){plotted}")
