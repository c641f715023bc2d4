"""``twin circle``: the circular test (ISO 230-4) on a machine scenario."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from twin_cosim.commands.console import command_line, write_summary
from twin_cosim.commands.options import (
    feed_override_option,
    no_plots_option,
    out_folder,
    output_options,
    scenario_parser,
)


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def add_circle(subparsers) -> None:
    """The ``circle`` command and its options."""
    parser = scenario_parser(
        subparsers,
        "circle",
        "circular test (ISO 230-4: G, H, F, reversal spikes) on a machine",
        run_circle,
        "machine scenario (axes: X, Y), file or shipped name",
    )
    parser.add_argument(
        "--radius", type=_positive, metavar="MM", help="radius, mm (required unless --measured)"
    )
    parser.add_argument(
        "--feed",
        type=_positive,
        metavar="MM_PER_MIN",
        help="feed, mm/min (required unless --measured)",
    )
    parser.add_argument(
        "--measured",
        metavar="RUN.csv",
        help="a measured circular test (t, x_ref, y_ref, x, y [, current_x, current_y]): "
        "replay it on the twin and diagnose the gap per axis (default: none, run the twin)",
    )
    parser.add_argument(
        "--direction", choices=["cw", "ccw", "both"], default="both", help="direction(s)"
    )
    feed_override_option(parser)
    parser.add_argument(
        "--params",
        help="ft|ga|ce|sa for every axis, or a YAML/JSON file (one set, or axes: {X: ..., Y: "
        "...}) (default: the scenario's)",
    )
    output_options(parser, "output folder (default: out/<name>-circle)", "result")
    no_plots_option(parser)
    parser.add_argument(
        "--reference-path",
        action="store_true",
        help="step through fmpy in plain Python instead of the compiled loop",
    )


def run_circle(args: argparse.Namespace) -> int:
    """Run the circle(s), write circle.json, circle.png and the records; print the result."""
    from twin_cosim.contour.circle_report import circular_test

    command = command_line("circle")
    default = Path("out") / f"{Path(args.scenario).stem}-circle"
    out = out_folder(args.out, default)
    if args.measured:
        return _measured(args, out, command)
    if args.radius is None or args.feed is None:
        from twin_cosim.scenario import load_machine

        load_machine(args.scenario)  # a scenario of no machine is named first
        raise ValueError("--radius MM and --feed MM_PER_MIN are required (unless --measured)")
    summary, draw = circular_test(
        args.scenario,
        args.radius,
        args.feed,
        args.direction,
        args.params,
        out,
        command,
        fast=not args.reference_path,
        feed_override=args.feed_override,
    )
    if write_summary(out / "circle.json", summary, args.json):
        _print_circle(args, summary, out)
    for warning in summary["warnings"]:
        print(f"twin circle: warning: {warning}", file=sys.stderr)
    if not args.no_plots:
        draw()
    return 0


def _print_circle(args: argparse.Namespace, summary: dict[str, Any], out: Path) -> None:
    """The circle's figures, spikes and ballbar's diagnostics, for people."""
    reached = summary["feed_reached_mm_min"]
    asked = args.feed * args.feed_override / 100
    feed = f"{reached:.0f} mm/min"
    if summary["warnings"] or args.feed_override != 100:
        feed += f" (programmed {args.feed:g} mm/min"
        feed += f", override {args.feed_override:g} %)" if args.feed_override != 100 else ")"
    elif abs(reached - asked) > 0.5:
        feed += f" (programmed {args.feed:g} mm/min)"
    print(
        f"circle R {args.radius:g} mm at {feed}: G {summary['G_um']:.2f} um, "
        f"F {summary['F_um']:.2f} um"
        + (f", H {summary['H_um']:.2f} um" if "H_um" in summary else "")
    )
    for spike in summary["spikes"]:
        print(
            f"  {spike['direction']:>3} {spike['angle_deg']:5.0f} deg ({spike['axis']} reverses): "
            f"spike {spike['height_um']:+.2f} um, {spike['width_ms']:.1f} ms"
        )
    print("  ballbar: " + ballbar_line(summary["ballbar"]))
    plot = "" if args.no_plots else ", circle.png"
    print(f"wrote {out}/circle.json{plot}, contour_<direction>.csv")


def _measured(args: argparse.Namespace, out: Path, command: str) -> int:
    """Replay and diagnose a measured test (the diagnosis of
    :func:`twin_cosim.contour.measured_circle.diagnose_circle`); write circle.json and
    circle.png (machine and twin); print the verdict."""
    from twin_cosim.contour.circle_report import paths_table, plot_circle
    from twin_cosim.contour.measured_circle import diagnose_circle, read_measured_circle
    from twin_cosim.scenario import load_machine

    machine = load_machine(args.scenario)
    test = read_measured_circle(args.measured)
    out.mkdir(parents=True, exist_ok=True)
    found = diagnose_circle(machine, test, not args.reference_path, workers=1)
    paths = found.pop("paths")
    if not args.no_plots:
        plot_circle(
            [("machine", paths["machine"]), ("twin", paths["twin"])],
            test.radius * 1e3,
            command,
            out / "circle.png",
            paths_table(paths, found["ballbar"]),
        )
    found["outputs"] = {"plot": None if args.no_plots else str(out / "circle.png")}
    found["outputs"]["folder"] = str(out)
    if not write_summary(out / "circle.json", found, args.json):
        return 0
    machine, twin = found["machine"], found["twin"]
    print(
        f"{args.measured}: G {machine['G_um']:.2f} um on the machine, {twin['G_um']:.2f} um on "
        "the twin"
    )
    for gap in found["transitions"]:
        print(
            f"  {gap['angle_deg']:5.0f} deg ({gap['axis']} reverses): spike machine "
            f"{gap['machine_height_um']:+.2f} um, twin {gap['twin_height_um']:+.2f} um"
        )
    print(found["verdict"]["text"])
    for name in ("machine", "twin"):
        print(f"  ballbar, {name}: " + ballbar_line(found["ballbar"][name]))
    print(f"wrote {out}/circle.json" + ("" if args.no_plots else ", circle.png"))
    return 0


def ballbar_line(figures: dict[str, Any]) -> str:
    """The ballbar's main figures in one line."""
    from twin_cosim.contour.circle_report import signed

    backlash = figures["backlash_um"]
    servo = figures["servo_mismatch_ms"]
    return (
        f"squareness {signed(figures['squareness_um_per_m'], 1)} um/m, scale mismatch X-Y "
        f"{signed(figures['scale_mismatch_um_per_m'], 1)} um/m, backlash X "
        f"{signed(backlash['X']['positive'])}/{signed(backlash['X']['negative'])} um, Y "
        f"{signed(backlash['Y']['positive'])}/{signed(backlash['Y']['negative'])} um"
        + (f", servo mismatch {signed(servo, 3)} ms" if servo is not None else "")
    )
