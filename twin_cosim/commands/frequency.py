"""The frequency-domain commands (docs/frequency.md): ``twin bode``, ``twin calibrate`` and
``twin autotune``.

- ``twin bode``: a loop's frequency response measured on the twin, as a drive measures it;
- ``twin calibrate``: the two-mass parameters fitted to a plant FRF, written as plant.yaml;
- ``twin autotune``: an FRF auto-tuner, the industrial baseline beside the optimizers.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin_cosim.commands.console import (
    command_line,
    scenario_of,
    warn_plant_mismatch,
    write_json,
    write_report,
    write_summary,
)
from twin_cosim.commands.options import (
    axis_test_options,
    coherence_option,
    data_option,
    no_plots_option,
    number_above,
    out_folder,
    output_options,
    plant_option,
    plant_parameters_option,
    plant_path,
    scenario_parser,
    whole_number,
)

LOOP_CHOICES = ("plant", "current", "speed", "position", "disturbance")  # current: the plant


def add_bode(subparsers) -> None:
    """The ``bode`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "bode",
        "measure a loop's frequency response in closed loop, with margins",
        run_bode,
    )
    parser.add_argument(
        "--loop",
        required=True,
        choices=LOOP_CHOICES,
        help="plant (or current: the excitation at the current command, the response the "
        "mechanics, eq. (3)), speed, position, or disturbance (a torque at the load, the "
        "dynamic stiffness in N/um) (required, no default)",
    )
    kind = parser.add_mutually_exclusive_group()
    kind.add_argument(
        "--open",
        dest="kind",
        action="store_const",
        const="open",
        help="the open loop L (default; the disturbance response is the closed cascade's)",
    )
    kind.add_argument(
        "--closed",
        dest="kind",
        action="store_const",
        const="closed",
        help="the closed loop T = L / (1 + L) (default: the open loop)",
    )
    kind.add_argument(
        "--sensitivity",
        dest="kind",
        action="store_const",
        const="sensitivity",
        help="the sensitivity S = 1 / (1 + L): the loop's error over its setpoint (default: "
        "the open loop)",
    )
    parser.set_defaults(kind=None)
    parser.add_argument(
        "--nonlinear",
        choices=("on", "off"),
        default="on",
        help="backlash, friction and the other nonlinearities of the plant model",
    )
    _excitation_options(parser)
    axis_test_options(parser, "out/bode-<scenario>-<loop>-<kind>")


def _excitation_options(parser: argparse.ArgumentParser) -> None:
    """Amplitude, averaging, operating point, noise, seed."""
    parser.add_argument(
        "--amplitude",
        type=number_above(0.0),
        help="RMS of the multisine: A (plant), rad/s (speed), m (position), N.m (disturbance) "
        "(default: what commands 2 %% of the current limit at high frequency; a disturbance of "
        "20 %% of the drive's friction torque)",
    )
    parser.add_argument(
        "--averages",
        type=whole_number(2),
        default=8,
        help="multisine realisations averaged",
    )
    parser.add_argument(
        "--speed",
        type=float,
        help="carriage speed of the operating point, m/s (0: standstill) (default: 20 rad/s at "
        "the motor, 0.0212 m/s on drive2mass: friction slides one way, the backlash stays "
        "closed, the loop responds as the linearised one)",
    )
    parser.add_argument(
        "--low", type=number_above(0.0), default=1.0, help="lowest excited frequency, Hz"
    )
    parser.add_argument(
        "--noise",
        type=number_above(0.0, inclusive=True),
        default=0.0,
        help="white noise on the measured motor speed, rad/s RMS",
    )
    parser.add_argument("--seed", type=whole_number(0), default=0, help="seed of phases and noise")
    coherence_option(
        parser, 0.9, "a margin or figure read at or above a line of lower coherence is withheld"
    )


def run_bode(args: argparse.Namespace) -> int:
    """Measure, write frf.csv, bode.png (nyquist.png; stiffness.png), bode.txt and bode.json;
    print the summary."""
    from twin_cosim.frequency.bode import bode, describe, write_bode
    from twin_cosim.frequency.measurement import MeasurementSettings

    scenario, mismatch = scenario_of(args)
    loop = "plant" if args.loop == "current" else args.loop
    how = MeasurementSettings(
        loop,
        args.kind,
        amplitude=args.amplitude,
        averages=args.averages,
        speed=args.speed,
        low_hz=args.low,
        speed_noise=args.noise,
        seed=args.seed,
    )
    out = out_folder(args.out, Path("out") / f"bode-{scenario.name}-{loop}-{how.kind}")
    result = bode(scenario, how, args.nonlinear == "on", plant_path(args), args.coherence_floor)
    files = write_bode(result, out, command_line("bode"), plots=not args.no_plots)
    table = "\n".join(describe(result)) + "\n"
    write_report(out, "bode", result.summary(), table, files, mismatch, args.json)
    return 0


def add_calibrate(subparsers) -> None:
    """The ``calibrate`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "calibrate",
        "fit J_M, J_L, f_1, D_1 and viscous friction to a plant FRF",
        run_calibrate,
        "scenario YAML file (or shipped name) of the machine",
    )
    parser.add_argument(
        "--frf",
        required=True,
        metavar="FRF.csv",
        help="plant FRF: f [Hz], magnitude_db and phase_deg (or real, imag) of motor speed over "
        "motor torque [rad/s per N.m], optional coherence; e.g. frf.csv of twin bode --loop "
        "plant (required, no default)",
    )
    coherence_option(parser, 0.8, "lines of lower coherence are masked (left out of the fit)")
    parser.add_argument(
        "--beside",
        metavar="PLANT.yaml",
        help="another calibration of the same machine to report beside, e.g. the plant.yaml of "
        "twin diagnose (default: none)",
    )
    output_options(parser, "output folder (default: out/calibrate-<scenario name>)")
    data_option(parser)


def run_calibrate(args: argparse.Namespace) -> int:
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
            f"{fit.drive_text()}"
        )
        print(f"wrote {', '.join(files.values())}, {out / 'calibration.json'}")
    return 0


def add_autotune(subparsers) -> None:
    """The ``autotune`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "autotune",
        "set Kp_vel, Ki_vel, a notch, Kp_pos and the feedforwards from the plant FRF",
        run_autotune,
    )
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
    coherence_option(parser, 0.8, "lines of the FRF file of lower coherence are left out")
    plant_option(parser)
    plant_parameters_option(parser)
    output_options(parser, "output folder (default: out/autotune-<scenario name>)")
    no_plots_option(parser)
    data_option(parser)


def run_autotune(args: argparse.Namespace) -> int:
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
