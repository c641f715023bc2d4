"""Blind test of the gap diagnosis: effects withheld from it, judged against the known answer.

For every case (an effect of the library at a large and a small magnitude, null runs with no
effect, and effects outside the library) and seed, ``twin synth`` makes a measured run of
``scenarios/diagnosis.yaml`` with the effect, a calibration error of up to ``--perturb`` on the
nominal parameters and white measurement noise; ``twin diagnose`` then runs without being told
the answer (it is judged on the first accepted effect, so the diagnosis stops after one). Prints
a confusion matrix (true effect against the first accepted effect or group),
the held-out shrink per effect, and the targets. Results are appended to ``--results`` as they
come, so an interrupted benchmark resumes where it stopped.

    python benchmarks/blind_gap.py [--seeds N] [--null-seeds N] [--perturb 0.02] [--results FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections import Counter, defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "diagnosis.yaml"
EFFECTS = {  # effect: (large, small), as twin synth --effect arguments
    "stribeck": (
        "stribeck_friction=0.3,stribeck_speed=0.47",
        "stribeck_friction=0.1,stribeck_speed=0.47",
    ),
    "coulomb_change": ("delta_coulomb=0.2", "delta_coulomb=0.05"),
    "asymmetric_friction": ("coulomb_asymmetry=0.15", "coulomb_asymmetry=0.04"),
    "position_friction": (
        "position_friction_amplitude=0.3,position_friction_phase=0.5",
        "position_friction_amplitude=0.1,position_friction_phase=0.5",
    ),
    "pitch_error": (
        "pitch_error_amplitude_1=5e-6,pitch_error_phase_1=0.3",
        "pitch_error_amplitude_1=1.5e-6,pitch_error_phase_1=0.3",
    ),
    "torque_ripple": (
        "ripple_amplitude=0.08,ripple_order=6",
        "ripple_amplitude=0.02,ripple_order=6",
    ),
    "current_lag": ("current_time_constant=5e-4", "current_time_constant=1.5e-4"),
    "dead_time": ("dead_time_steps=8", "dead_time_steps=2"),
    "quantization": ("position_resolution=1e-6", "position_resolution=1e-7"),
    "backlash_change": ("delta_backlash=10e-6", "delta_backlash=2e-6"),
    "inertia_change": ("relative_change=0.3", "relative_change=0.08"),
    "stiffness_change": ("relative_change=-0.4", "relative_change=-0.1"),
}
OUTSIDE = {
    "lugre_friction": "plant:lugre_stiffness=1000,lugre_damping=0.05",
    "pitch_harmonic_3": "plant:pitch_error_amplitude_3=3e-6,pitch_error_phase_3=0.4",
    "thermal_drift": "plant:thermal_expansion_rate=1e-4",
}


def cases(seeds: int, null_seeds: int) -> list[dict]:
    found = []
    for effect, (large, small) in EFFECTS.items():
        for size, params in (("large", large), ("small", small)):
            for seed in range(seeds):
                found.append(
                    {"truth": effect, "size": size, "effect": f"{effect}:{params}", "seed": seed}
                )
    for seed in range(null_seeds):
        found.append({"truth": "none", "size": "null", "effect": None, "seed": 100 + seed})
    for name, spec in OUTSIDE.items():
        for seed in range(max(1, seeds // 2)):
            found.append({"truth": name, "size": "outside", "effect": spec, "seed": 200 + seed})
    return found


def twin(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "twin_cosim", *args], capture_output=True, text=True, cwd=ROOT
    )


def run_case(case: dict, perturb: float, folder: Path) -> dict:
    run = folder / "run.csv"
    synth = [
        "synth",
        str(SCENARIO),
        "--perturb",
        str(perturb),
        "--seed",
        str(case["seed"]),
        "--out",
        str(run),
    ]
    if case["effect"]:
        synth += ["--effect", case["effect"]]
    made = twin(*synth)
    if made.returncode != 0:
        raise RuntimeError(made.stderr)
    result = twin(
        "diagnose",
        str(SCENARIO),
        "--measured",
        str(run),
        "--out",
        str(folder / "report"),
        "--max-effects",
        "1",
        "--json",
    )
    if result.returncode != 0:
        raise RuntimeError(result.stderr)
    summary = json.loads(result.stdout)
    first = summary["accepted"][0] if summary["accepted"] else "none"
    step = summary["steps"][0] if summary["steps"] else None
    return {
        **case,
        "accepted": summary["accepted"],
        "first": first,
        "top3": [row["name"] for row in summary["effects"][:3]],
        "reduction": step["reduction"] if step else 0.0,
        "gap_before_um": summary["effects"][0]["holdout_gap_before_um"]
        if summary["effects"]
        else None,
        "gap_after_um": step["holdout_gap_after_um"] if step else None,
        "significant": summary["gap"]["significant"],
        "verdict": summary["gap"]["verdict"],
        "wall_s": summary["wall_s"],
    }


def names(item) -> set[str]:
    return set(item) if isinstance(item, list) else {item}


def report(results: list[dict]) -> None:
    labels = sorted({r["truth"] for r in results})
    columns = sorted({" | ".join(sorted(names(r["first"]))) for r in results})
    counts = Counter((r["truth"], " | ".join(sorted(names(r["first"])))) for r in results)
    print("\nConfusion matrix (rows: injected; columns: first accepted effect or group; all sizes)")
    print("injected".ljust(22) + "".join(c[:14].rjust(15) for c in columns))
    for label in labels:
        print(label.ljust(22) + "".join(str(counts[(label, c)] or ".").rjust(15) for c in columns))
    print(
        "\nPer effect (large / small): right first, mean held-out reduction when right, "
        "right in top 3"
    )
    by = defaultdict(list)
    for r in results:
        by[(r["truth"], r["size"])].append(r)
    for effect in EFFECTS:
        cells = []
        for size in ("large", "small"):
            group = by[(effect, size)]
            right = [r for r in group if effect in names(r["first"])]
            shrink = sum(r["reduction"] for r in right) / len(right) if right else 0.0
            top3 = sum(effect in r["top3"] for r in group)
            cells.append(
                f"{size}: {len(right)}/{len(group)} first, {shrink:.0%} shrink, "
                f"{top3}/{len(group)} top-3"
            )
        print(f"  {effect:<20} " + "; ".join(cells))
    large = [r for r in results if r["size"] == "large"]
    small = [r for r in results if r["size"] == "small"]
    null = [r for r in results if r["size"] == "null"]
    outside = [r for r in results if r["size"] == "outside"]
    large_ok = [r for r in large if r["truth"] in names(r["first"]) and r["reduction"] >= 0.5]
    small_ok = [r for r in small if r["truth"] in r["top3"]]
    null_ok = [r for r in null if not r["accepted"]]
    print("\nTargets")
    print(f"  null runs with no acceptance: {len(null_ok)}/{len(null)} (target >= 95 %)")
    print(
        "  large effects right first with >= 50 % held-out reduction: "
        f"{len(large_ok)}/{len(large)} "
        "(target >= 90 %)"
    )
    print(f"  small effects right in the top 3: {len(small_ok)}/{len(small)} (target >= 70 %)")
    print("  outside the library (accepted / verdict):")
    for r in outside:
        print(f"    {r['truth']} seed {r['seed']}: {r['accepted'] or 'nothing'}; {r['verdict']}")
    undiagnosable = [r for r in small if not r["accepted"]]
    print(f"  small effects declared without an accepted effect: {len(undiagnosable)}/{len(small)}")
    walls = [r["wall_s"] for r in results]
    print(
        f"  diagnosis wall time: median {sorted(walls)[len(walls) // 2]:.1f} s, "
        f"max {max(walls):.1f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2, help="seeds per effect and size")
    parser.add_argument("--null-seeds", type=int, default=10)
    parser.add_argument("--perturb", type=float, default=0.02)
    parser.add_argument("--results", default="out/blind_gap.jsonl")
    args = parser.parse_args()
    path = Path(args.results)
    path.parent.mkdir(parents=True, exist_ok=True)
    done = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    finished = {(r["truth"], r["size"], r["seed"]) for r in done}
    for case in cases(args.seeds, args.null_seeds):
        if (case["truth"], case["size"], case["seed"]) in finished:
            continue
        with tempfile.TemporaryDirectory() as tmp:
            result = run_case(case, args.perturb, Path(tmp))
        done.append(result)
        with path.open("a") as log:
            log.write(json.dumps(result) + "\n")
        print(
            f"{case['truth']:<20} {case['size']:<8} seed {case['seed']:<4} -> {result['first']} "
            f"({result['reduction']:.0%}, {result['wall_s']:.0f} s)",
            flush=True,
        )
    report(done)


if __name__ == "__main__":
    main()
