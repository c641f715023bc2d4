"""``twin synth MACHINE``: a measured circular test or program run of a virtual machine.

The machine branch of :mod:`twin_cosim.commands.synth` (a scenario with ``axes:``): the circle
(``--radius``, ``--feed``, ``--direction``) or the part program (``--program``, else the
scenario's) runs on the machine with effects switched on per axis (``--effect AXIS:NAME:...``),
calibration error and measurement noise, and its geometric errors
(:func:`twin_cosim.contour.circle_diagnosis.synthesize_motion`); the CSV is a measured test for
``twin circle MACHINE --measured RUN.csv``, and ``RUN.csv.truth.json`` holds the answer.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from twin_cosim.commands.console import write_json

if TYPE_CHECKING:
    from twin_cosim.gap.synth import EffectSpec
    from twin_cosim.scenario.machine import MachineScenario

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
    from twin_cosim.contour.circle_diagnosis import synthesize_motion
    from twin_cosim.contour.gcode import read_program
    from twin_cosim.contour.machine_run import plan_on
    from twin_cosim.scenario import load_machine

    for option in _SINGLE_AXIS_OPTIONS:
        if getattr(args, option, None):
            raise ValueError(f"--{option}: for a single-axis scenario, not a machine (axes:)")
    out, truth = _files(args)
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


def _files(args: argparse.Namespace) -> tuple[Path, Path]:
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
