"""Blind test of the gap diagnosis: effects withheld from it, judged against the known answer.

Two suites; in both ``twin synth`` makes a measured run with the effects, a calibration error of
up to ``--perturb`` on the nominal parameters and white measurement noise, and ``twin diagnose``
runs without being told the answer. Results are appended to ``--results`` as they come, so an
interrupted benchmark resumes where it stopped.

- ``library`` (``scenarios/diagnosis.yaml``): every effect of the library at a large and a small
  magnitude, null runs and effects outside the library; judged on the first accepted effect
  (the diagnosis stops after one). Prints a confusion matrix, the held-out shrink per effect and
  the targets.
- ``unseen``: cases the diagnosis was not tuned on, on a second trajectory
  (``scenarios/sweep.yaml``) besides the first: other magnitudes, both signs, orders other than
  6, pairs of effects (up to three effects accepted), clean null runs, and effects outside the
  library, one of them a tight spot of the guideway built as a patched copy of drive2mass at run
  time (``tests/tight_spot.py``, shared with the tests). Prints one line per case and the
  targets.

    python benchmarks/blind_gap.py [--suite library|unseen] [--seeds N] [--null-seeds N]
                                   [--perturb 0.02] [--results FILE]
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
SWEEP = ROOT / "scenarios" / "sweep.yaml"
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


# The unseen suite: (name, scenario, kind, effects, synth options, spot (mm) of a local defect)
UNSEEN_SINGLES = {
    "stribeck": "stribeck:stribeck_friction=0.2,stribeck_speed=0.3",
    "coulomb_change": "coulomb_change:delta_coulomb=-0.15",
    "asymmetric_friction": "asymmetric_friction:coulomb_asymmetry=-0.1",
    "position_friction": "position_friction:position_friction_amplitude=0.25,"
    "position_friction_phase=1.0,position_friction_order=2",
    "pitch_error": "pitch_error:pitch_error_amplitude_1=3e-6,pitch_error_phase_1=-0.5",
    "torque_ripple": "torque_ripple:ripple_amplitude=0.05,ripple_order=4",
    "current_lag": "current_lag:current_time_constant=3e-4",
    "dead_time": "dead_time:dead_time_steps=5",
    "backlash_change": "backlash_change:delta_backlash=-5e-6",
    "inertia_change": "inertia_change:relative_change=-0.2",
    "stiffness_change": "stiffness_change:relative_change=0.5",
}
UNSEEN_PAIRS = {
    "stribeck+torque_ripple": (
        "stribeck:stribeck_friction=0.25,stribeck_speed=0.3",
        "torque_ripple:ripple_amplitude=0.04,ripple_order=6",
    ),
    "coulomb_change+torque_ripple": (
        "coulomb_change:delta_coulomb=0.15",
        "torque_ripple:ripple_amplitude=0.05,ripple_order=8",
    ),
    "inertia_change+backlash_change": (
        "inertia_change:relative_change=0.25",
        "backlash_change:delta_backlash=8e-6",
    ),
    "asymmetric_friction+pitch_error": (
        "asymmetric_friction:coulomb_asymmetry=0.1",
        "pitch_error:pitch_error_amplitude_1=3e-6,pitch_error_phase_1=0.8",
    ),
}
TIGHT_SPOTS = {  # name: (relative rise of friction, centre m, half width m)
    "tight_spot_25mm": (1.0, 0.025, 0.5e-3),
    "tight_spot_12mm": (0.6, 0.012, 1.0e-3),
}


def unseen_cases(perturb: float) -> list[dict]:
    found = []
    for i, (name, spec) in enumerate(UNSEEN_SINGLES.items()):
        scenario = SWEEP if i % 3 else SCENARIO
        found.append(
            {
                "truth": name,
                "size": "single",
                "effects": [spec],
                "seed": 300 + i,
                "scenario": str(scenario),
                "perturb": perturb,
            }
        )
    for i, (name, specs) in enumerate(UNSEEN_PAIRS.items()):
        found.append(
            {
                "truth": name,
                "size": "pair",
                "effects": list(specs),
                "seed": 400 + i,
                "scenario": str(SWEEP if i % 2 == 0 else SCENARIO),
                "perturb": perturb,
            }
        )
    for i, scenario in enumerate((SWEEP, SWEEP, SCENARIO, SCENARIO)):
        found.append(
            {
                "truth": "none",
                "size": "null",
                "effects": [],
                "seed": 500 + i,
                "scenario": str(scenario),
                "perturb": 0.0,
            }
        )
    for i in range(2):
        found.append(
            {
                "truth": "none",
                "size": "null",
                "effects": [],
                "seed": 510 + i,
                "scenario": str(SWEEP),
                "perturb": perturb,
            }
        )
    for i, name in enumerate(TIGHT_SPOTS):
        found.append(
            {
                "truth": name,
                "size": "outside",
                "effects": [],
                "seed": 600 + i,
                "scenario": str(SWEEP),
                "perturb": perturb,
                "spot": name,
            }
        )
    for i, (name, spec) in enumerate(OUTSIDE.items()):
        if name == "thermal_drift":
            continue
        found.append(
            {
                "truth": name,
                "size": "outside",
                "effects": [spec],
                "seed": 610 + i,
                "scenario": str(SWEEP),
                "perturb": perturb,
            }
        )
    return found


def run_unseen_case(case: dict, folder: Path) -> dict:
    """Synthesise and diagnose one case of the unseen suite (up to three effects accepted)."""
    sys.path.insert(0, str(ROOT / "tests"))  # the tight spot is the tests' (tests/tight_spot.py)
    from tight_spot import build_tight_spot_fmu

    run = folder / "run.csv"
    synth = [
        "synth",
        case["scenario"],
        "--perturb",
        str(case["perturb"]),
        "--seed",
        str(case["seed"]),
        "--out",
        str(run),
    ]
    for effect in case["effects"]:
        synth += ["--effect", effect]
    if case.get("spot"):
        synth += ["--plant", str(build_tight_spot_fmu(*TIGHT_SPOTS[case["spot"]], folder))]
    made = twin(*synth)
    if made.returncode != 0:
        raise RuntimeError(made.stderr)
    result = twin(
        "diagnose",
        case["scenario"],
        "--measured",
        str(run),
        "--out",
        str(folder / "report"),
        "--json",
    )
    if result.returncode != 0:
        return {**case, "crashed": result.stderr[-2000:]}
    summary = json.loads(result.stdout)
    accepted = (
        sorted(set().union(*(names(a) for a in summary["accepted"]))) if summary["accepted"] else []
    )
    steps = summary["steps"]
    before = summary["rounds"][0]["holdout_normalised_rms"]
    after = steps[-1]["holdout_normalised_rms_after"] if steps else before
    return {
        **case,
        "accepted": summary["accepted"],
        "accepted_names": accepted,
        "first": summary["accepted"][0] if summary["accepted"] else "none",
        "reduction": 1.0 - after / before if before else 0.0,
        "significant": summary["gap"]["significant"],
        "verdict": summary["gap"]["verdict"],
        "remaining": summary["gap"]["remaining"]["text"],
        "along_axis": summary["where"]["along_axis"][:3],
        "wall_s": summary["wall_s"],
    }


def judge_unseen(r: dict) -> bool:
    """Whether a case of the unseen suite is right (see the targets in report_unseen)."""
    if "crashed" in r:
        return False
    if r["size"] == "null":
        return not r["accepted"] and not r["significant"]
    if r["size"] == "single":
        return r["truth"] in names(r["first"]) and r["reduction"] >= 0.5
    if r["size"] == "pair":
        return set(r["truth"].split("+")) <= set(r["accepted_names"])
    if r.get("spot"):
        centre_mm = TIGHT_SPOTS[r["spot"]][1] * 1e3
        spans = r["along_axis"]
        located = (
            bool(spans) and abs(0.5 * (spans[0]["from_mm"] + spans[0]["to_mm"]) - centre_mm) <= 2.0
        )
        return not r["accepted"] and located
    return not r["accepted"]


def report_unseen(results: list[dict]) -> None:
    print("\nPer case (truth, size, scenario, seed: accepted; held-out reduction; wall time)")
    for r in results:
        mark = "ok " if judge_unseen(r) else "MISS"
        if "crashed" in r:
            print(f"  {mark} {r['truth']:<32} CRASHED: {r['crashed'].splitlines()[-1]}")
            continue
        where = ""
        if r["size"] == "outside" and r["along_axis"]:
            s = r["along_axis"][0]
            where = f"; first span {s['from_mm']:.1f}-{s['to_mm']:.1f} mm ({s['direction']:+d})"
        print(
            f"  {mark} {r['truth']:<32} {r['size']:<7} {Path(r['scenario']).stem:<9} seed "
            f"{r['seed']}: {r['accepted'] or 'nothing'}; {r['reduction']:.0%}; "
            f"{r['wall_s']:.0f} s{where}"
        )
    print("\nTargets")
    for size, label, target in (
        ("null", "null runs: nothing accepted, no false alarm", "all"),
        ("single", "single effects: right first, >= 50 % held-out reduction", ">= 9 of 10"),
        ("pair", "pairs: both effects found", ">= 3 of 4"),
        ("outside", "outside the library: not named; tight spots located within 2 mm", "all"),
    ):
        group = [r for r in results if r["size"] == size]
        print(f"  {label}: {sum(map(judge_unseen, group))}/{len(group)} (target {target})")
    stated = [r for r in results if r.get("remaining")]
    print(f"  remaining gap stated: {len(stated)}/{len(results)}")
    crashed = [r for r in results if "crashed" in r]
    print(f"  crashes: {len(crashed)}")
    walls = sorted(r["wall_s"] for r in results if "wall_s" in r)
    if walls:
        print(
            f"  diagnosis wall time: median {walls[len(walls) // 2]:.1f} s, max {walls[-1]:.1f} s"
        )


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
    parser.add_argument("--suite", choices=("library", "unseen"), default="library")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per effect and size")
    parser.add_argument("--null-seeds", type=int, default=10)
    parser.add_argument("--perturb", type=float, default=0.02)
    parser.add_argument("--results", help="default: out/blind_gap[-unseen].jsonl")
    args = parser.parse_args()
    default = "out/blind_gap.jsonl" if args.suite == "library" else "out/blind_gap-unseen.jsonl"
    path = Path(args.results or default)
    path.parent.mkdir(parents=True, exist_ok=True)
    done = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    finished = {(r["truth"], r["size"], r["seed"]) for r in done}
    if args.suite == "unseen":
        for case in unseen_cases(args.perturb):
            if (case["truth"], case["size"], case["seed"]) in finished:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                result = run_unseen_case(case, Path(tmp))
            done.append(result)
            with path.open("a") as log:
                log.write(json.dumps(result) + "\n")
            print(f"{case['truth']:<32} {case['size']:<8} -> {result.get('accepted')}", flush=True)
        report_unseen(done)
        return
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
