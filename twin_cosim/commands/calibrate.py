"""``twin calibrate``: the two-mass parameters fitted to a plant FRF, written as plant.yaml."""

from __future__ import annotations

import argparse
from pathlib import Path

from twin_cosim.commands.console import command_line, write_summary
from twin_cosim.commands.options import (
    command_parser,
    data_option,
    fraction,
    out_folder,
    output_options,
)


def add_arguments(subparsers) -> None:
    """The ``calibrate`` command and its options."""
    parser = command_parser(
        subparsers, "calibrate", "fit J_M, J_L, f_1, D_1 and viscous friction to a plant FRF", run
    )
    parser.add_argument("scenario", help="scenario YAML file (or shipped name) of the machine")
    parser.add_argument(
        "--frf",
        required=True,
        metavar="FRF.csv",
        help="plant FRF: f [Hz], magnitude_db and phase_deg (or real, imag) of motor speed over "
        "motor torque [rad/s per N.m], optional coherence; e.g. frf.csv of twin bode --loop "
        "plant (required, no default)",
    )
    parser.add_argument(
        "--coherence-floor",
        type=fraction(0.0, 1.0),
        default=0.8,
        help="lines of lower coherence are masked (left out of the fit)",
    )
    parser.add_argument(
        "--beside",
        metavar="PLANT.yaml",
        help="another calibration of the same machine to report beside, e.g. the plant.yaml of "
        "twin diagnose (default: none)",
    )
    output_options(parser, "output folder (default: out/calibrate-<scenario name>)")
    data_option(parser)


def run(args: argparse.Namespace) -> int:
    """Read and check the FRF, fit, write plant.yaml, calibration.md, fit.png, calibration.json."""
    from twin_cosim.frequency.bode import plot_bode
    from twin_cosim.frequency.calibration import calibrate, read_frf, write_calibration_files
    from twin_cosim.scenario import resolve_scenario

    scenario = resolve_scenario(args.scenario)
    out = out_folder(args.out, Path("out") / f"calibrate-{scenario.name}")
    frf = read_frf(args.frf, args.coherence_floor)
    command = command_line("calibrate")
    calibration = calibrate(scenario, frf, command, Path(args.beside) if args.beside else None)
    files = write_calibration_files(calibration, out)
    title = f"{frf.source}: the two-mass fit\n{command}"
    files["plot"] = str(plot_bode(calibration.responses(), title, out / "fit.png"))
    notes = frf.notes(args.coherence_floor)
    summary = {**calibration.summary(), "notes": notes, "outputs": files}
    if write_summary(out / "calibration.json", summary, args.json):
        for note in notes:
            print(f"twin calibrate: {note}")
        print(calibration.markdown())
        fit = calibration.fit
        print(
            f"fit: {fit.lines} lines, RMS error {fit.rms_db:.3g} dB, {fit.rms_deg:.3g} deg, "
            f"delay {fit.delay_s * 1e6:.3g} us, current lag {fit.lag_s * 1e6:.3g} us"
        )
        print(f"wrote {', '.join(files.values())}, {out / 'calibration.json'}")
    return 0
