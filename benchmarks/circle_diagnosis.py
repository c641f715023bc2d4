"""Blind test of the circular test's diagnosis on virtual X-Y machines (docs/contouring.md).

Each case hides one effect of the plant-model library in one axis of ``scenarios/xy_table.yaml``
(plus a calibration error of up to ``--perturb`` on both axes' calibrated parameters and white
measurement noise), runs a circle on that virtual machine
(:func:`twin_cosim.contour.measured_circle.synthesize_motion` of the circle), writes it as a
measured test and lets the diagnosis
(:func:`twin_cosim.contour.measured_circle.diagnose_circle`) name the axis and the effect
without being told. A case counts when both are right (the effect may stand in
an accepted look-alike group). Results are appended to ``--results`` as they come.

    python benchmarks/circle_diagnosis.py [--perturb 0.02] [--results FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, circle_motion
from twin_cosim.contour.measured_circle import (
    diagnose_circle,
    read_measured_circle,
    synthesize_motion,
)
from twin_cosim.gap.synth import parse_effect
from twin_cosim.scenario import load_machine

CASES = (  # (axis, effect as twin synth --effect, radius mm, feed mm/min, direction)
    ("Y", "stribeck:stribeck_friction=0.3,stribeck_speed=0.47", 10, 1000, "ccw"),
    ("X", "backlash_change:delta_backlash=20e-6", 10, 1000, "cw"),
    ("Y", "coulomb_change:delta_coulomb=0.2", 5, 2000, "ccw"),
    ("X", "asymmetric_friction:coulomb_asymmetry=0.2", 10, 1000, "ccw"),
    ("Y", "inertia_change:relative_change=0.3", 5, 2000, "cw"),
    ("X", "current_lag:current_time_constant=1e-3", 10, 2000, "ccw"),
    ("Y", "dead_time:dead_time_steps=3", 10, 1000, "cw"),
    ("X", "stribeck:stribeck_friction=0.2,stribeck_speed=0.3", 25, 1000, "ccw"),
    ("Y", "backlash_change:delta_backlash=15e-6", 25, 500, "ccw"),
    ("X", "coulomb_change:delta_coulomb=0.25", 5, 1000, "cw"),
)


def _named(accepted: list, effect: str) -> bool:
    """Whether the first accepted effect (or look-alike group) holds ``effect``."""
    if not accepted:
        return False
    first = accepted[0]
    return effect == first or (isinstance(first, list) and effect in first)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--perturb", type=float, default=0.02)
    parser.add_argument("--results", type=Path, default=Path("out/circle_diagnosis.jsonl"))
    args = parser.parse_args()
    args.results.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if args.results.exists():
        for line in args.results.read_text().splitlines():
            row = json.loads(line)
            done[row["case"]] = row
    machine = load_machine("xy_table")
    for case, (axis, effect, radius, feed, direction) in enumerate(CASES):
        if case in done:
            continue
        spec = CircleSpec(radius * 1e-3, feed * MM_PER_MIN, direction)
        motion, _ = circle_motion(machine, spec)
        table = synthesize_motion(
            machine, motion, {axis: [parse_effect(effect)]}, args.perturb, seed=case
        )
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "measured.csv"
            table.frame().to_csv(path, index=False)
            found = diagnose_circle(machine, read_measured_circle(path))
        verdict = found["verdict"]
        name = effect.split(":")[0]
        accepted = found["axes"].get(axis, {}).get("accepted", [])
        row = {
            "case": case,
            "truth": {"axis": axis, "effect": name, "radius_mm": radius, "feed_mm_min": feed},
            "verdict": {k: verdict[k] for k in ("axis", "effect", "transition_deg")},
            "accepted": {k: v["accepted"] for k, v in found["axes"].items()},
            "right": verdict["axis"] == axis and _named(accepted, name),
        }
        with args.results.open("a") as stream:
            stream.write(json.dumps(row) + "\n")
        done[case] = row
        print(
            f"case {case}: {axis} {name} -> {verdict['axis']} {verdict['effect']} "
            f"({'right' if row['right'] else 'wrong'})",
            flush=True,
        )
    right = sum(row["right"] for row in done.values())
    print(f"named axis and effect in {right} of {len(done)} (goal: 8 of 10)")


if __name__ == "__main__":
    main()
