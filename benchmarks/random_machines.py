"""The gap diagnosis judged as a detector on seeded random virtual machines.

Each machine (``machine_of(seed)``) has 0 to 3 effects of the drive2mass library at random
moderate sizes and signs (pairs and triples that share a regime are drawn more often, e.g.
Stribeck with Coulomb and backlash), a calibration error of up to 2 % on every calibrated
parameter, its own noise seed, and one excitation: ``scenarios/diagnosis.yaml``,
``scenarios/sweep.yaml`` or a seeded random excitation inside the shipped motion envelope
(``random_excitation``). For each machine, through the command line: ``twin synth`` makes the
measured run, ``twin diagnose`` (time split) says what it finds. Scored per machine:

- recall: true effects accepted (an accepted look-alike group that holds the truth counts);
- precision: accepted effects (or groups) that hold a true effect;
- null machines (no effect) with anything accepted;
- the held-out reduction of the normalised RMS by the final model, the wall time.

Thresholds are chosen on the ``--tune`` seeds and reported on the ``--report`` seeds (disjoint
ranges); results are appended to ``<out>/results.jsonl`` as they come (an interrupted run
resumes), and the report prints both sets' figures, a per-effect confusion table and where the
time went::

    python benchmarks/random_machines.py --tune 0-19 --report 100-159 [--workers 2]
                                         [--out out/random-machines]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = {
    "diagnosis": ROOT / "scenarios" / "diagnosis.yaml",
    "sweep": ROOT / "scenarios" / "sweep.yaml",
}
# Excitation of a machine and its probability: the shipped ones last 11-12 s, a random one 4-7 s
# (the time a benchmark of 60 machines may take on two shared cores decides the mix).
EXCITATIONS = {"diagnosis": 0.1, "sweep": 0.05, "random": 0.85}
PERTURB = 0.02  # calibration error, relative
EFFECT_COUNTS = (0, 1, 2, 3)
COUNT_WEIGHTS = (0.15, 0.3, 0.3, 0.25)
# Effects with their moderate size ranges, as twin synth parameters: (low, high, signed).
EFFECTS: dict[str, dict[str, tuple[float, float, bool]]] = {
    "stribeck": {"stribeck_friction": (0.08, 0.3, False), "stribeck_speed": (0.2, 0.8, False)},
    "coulomb_change": {"delta_coulomb": (0.05, 0.2, True)},
    "asymmetric_friction": {"coulomb_asymmetry": (0.04, 0.15, True)},
    "position_friction": {
        "position_friction_amplitude": (0.1, 0.3, False),
        "position_friction_phase": (0.0, 2 * math.pi, False),
    },
    "pitch_error": {
        "pitch_error_amplitude_1": (1.5e-6, 5e-6, False),
        "pitch_error_phase_1": (0.0, 2 * math.pi, False),
    },
    "torque_ripple": {
        "ripple_amplitude": (0.02, 0.08, False),
        "ripple_phase": (0.0, 2 * math.pi, False),
    },
    "current_lag": {"current_time_constant": (1.5e-4, 5e-4, False)},
    "dead_time": {"dead_time_steps": (2.0, 6.0, False)},
    "backlash_change": {"delta_backlash": (3e-6, 10e-6, True)},
    "inertia_change": {"relative_change": (0.08, 0.3, True)},
    "stiffness_change": {"relative_change": (0.1, 0.4, True)},
}
# Effects that share a regime (reversals, breakaway): drawn together more often.
SHARED_REGIME = ("stribeck", "coulomb_change", "backlash_change", "asymmetric_friction")
WHOLE = {"dead_time_steps"}
ALIKE = [{"current_lag", "dead_time"}]  # look-alikes the data cannot tell apart


def draw_effects(rng: np.random.Generator) -> list[str]:
    """0-3 effects at random moderate sizes, as ``twin synth --effect`` arguments."""
    count = int(rng.choice(EFFECT_COUNTS, p=COUNT_WEIGHTS))
    names = sorted(EFFECTS)
    if count >= 2 and rng.uniform() < 0.4:  # a set that shares the reversal regime
        chosen = list(rng.choice(SHARED_REGIME, size=count, replace=False))
    else:
        chosen = list(rng.choice(names, size=count, replace=False))
    if {"current_lag", "dead_time"} <= set(chosen):  # look-alikes: keep one
        chosen.remove("dead_time")
    effects = []
    for name in sorted(chosen):
        values = {}
        for parameter, (low, high, signed) in EFFECTS[name].items():
            value = float(rng.uniform(low, high))
            if parameter in WHOLE:
                value = float(round(value))
            if signed and rng.uniform() < 0.5:
                value = -value
            if parameter == "delta_backlash":
                value = max(value, -6e-6)  # the nominal backlash is 12.2 um
            values[parameter] = value
        effects.append(f"{name}:" + ",".join(f"{k}={v:.4g}" for k, v in values.items()))
    return effects


def random_excitation(seed: int, path: Path) -> Path:
    """A seeded random excitation inside the shipped motion envelope, written as a scenario.

    The same pattern twice (the time split trains and judges on alike data): a dwell, two
    constant speeds (10-45 mm/s) in both directions reached at 0.2-0.5 m/s^2, a reversal while
    moving at 0.05-0.2 m/s^2, a stop, a dwell and a move back to the start at the faster speed
    (a reversal after a dwell). A pattern lasts about 2-3 s (the shipped excitations 6 s): a
    benchmark of many machines replays it some thousands of times per machine.
    """
    rng = np.random.default_rng(seed)
    slow, fast = (float(v) for v in sorted(rng.uniform(0.01, 0.045, size=2)))
    accel = float(rng.uniform(0.2, 0.5))
    reverse = float(rng.uniform(0.05, 0.2))
    dwell = round(float(rng.uniform(0.15, 0.3)), 3)
    first, second = (1.0, -1.0) if rng.uniform() < 0.5 else (-1.0, 1.0)

    def ramp(speed: float, acceleration: float, hold: float, previous: float) -> dict:
        duration = abs(speed - previous) / acceleration + hold
        return {
            "ramp": {
                "velocity": round(speed, 4),
                "acceleration": round(acceleration, 3),
                "duration": round(duration, 3),
            }
        }

    pattern = [
        {"dwell": dwell},
        ramp(first * slow, accel, 0.3, 0.0),
        ramp(first * fast, accel, 0.25, first * slow),
        ramp(second * slow, reverse, 0.25, first * fast),
        ramp(second * fast, accel, 0.25, second * slow),
        ramp(0.0, accel, 0.05, second * fast),
        {"dwell": dwell},
        {"move": {"to": 0.0, "velocity": round(fast, 4), "acceleration": round(accel, 3)}},
    ]
    scenario = {
        "name": path.stem,
        "description": f"random excitation, seed {seed} (benchmarks/random_machines.py)",
        "controller": {"parameters": "ft"},
        "reference": {"sample_period": 0.004, "start_position": 0.0, "segments": pattern * 2},
        "run": {"metrics_window": [0.0, None]},
    }
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


def machine_of(seed: int) -> dict:
    """The machine of a seed: effects, excitation and synth seed."""
    rng = np.random.default_rng([7919, seed])
    excitation = str(rng.choice(list(EXCITATIONS), p=list(EXCITATIONS.values())))
    return {"seed": seed, "effects": draw_effects(rng), "excitation": excitation}


def _children_cpu_s() -> float:
    """CPU seconds (user + system) of the finished child processes and theirs."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def twin(*args: str) -> subprocess.CompletedProcess:
    """``twin ARGS`` through the running interpreter's package."""
    return subprocess.run(
        [sys.executable, "-m", "twin_cosim", *args], capture_output=True, text=True, cwd=ROOT
    )


def truth_names(effects: list[str]) -> list[str]:
    """The library names of a machine's effects."""
    return sorted(e.split(":", 1)[0] for e in effects)


def run_machine(case: dict, folder: Path, workers: int) -> dict:
    """Synthesise and diagnose one machine; the summary's figures that the scoring needs."""
    folder.mkdir(parents=True, exist_ok=True)
    if case["excitation"] == "random":
        scenario = random_excitation(case["seed"], folder / f"excitation{case['seed']}.yaml")
    else:
        scenario = SHIPPED[case["excitation"]]
    run = folder / "run.csv"
    synth = ["synth", str(scenario), "--perturb", str(PERTURB), "--seed", str(case["seed"])]
    synth += ["--out", str(run), "--force"]
    for effect in case["effects"]:
        synth += ["--effect", effect]
    made = twin(*synth)
    if made.returncode != 0:
        raise RuntimeError(f"synth {case}: {made.stderr}")
    start = time.perf_counter()
    cpu_start = _children_cpu_s()
    diagnosed = twin(
        "diagnose",
        str(scenario),
        "--measured",
        str(run),
        "--out",
        str(folder / "report"),
        "--workers",
        str(workers),
        "--json",
        "--quiet",
        "--no-plots",
    )
    wall = time.perf_counter() - start
    cpu = _children_cpu_s() - cpu_start
    if diagnosed.returncode != 0:
        return {**case, "crashed": diagnosed.stderr[-2000:], "wall_s": wall, "cpu_s": cpu}
    summary = json.loads(diagnosed.stdout)
    rounds = summary["rounds"]
    remaining = summary["gap"]["remaining"]  # the final model's (after swaps, backward pass)
    before, after = remaining["normalised_rms_before"], remaining["times_noise_floor"]
    return {
        **case,
        "truth": truth_names(case["effects"]),
        "accepted": summary["accepted"],
        "significant": summary["gap"]["significant"],
        "swaps": [[w["removed"], w["name"]] for w in summary.get("swaps", []) if w["kept"]],
        "reduction": 1.0 - after / before if before else 0.0,
        "wall_s": wall,
        "cpu_s": cpu,
        "load": os.getloadavg()[0],
        "diagnosis_wall_s": summary.get("wall_s"),
        "time": summary.get("time", {}),
        "rounds": [
            {
                "significant": r["significant"],
                "left": r["calibration"]["left"],
                "accepted": r["accepted"],
            }
            for r in rounds
        ],
    }


def members(item) -> set[str]:
    """The effect names of an accepted item (a name or a look-alike group)."""
    names = set(item) if isinstance(item, list) else {item}
    for group in ALIKE:
        if names & group:
            names |= group
    return names


def score(results: list[dict]) -> dict:
    """Recall, precision, null false alarms, reductions and wall times of a set of machines."""
    found = true_total = accepted_total = accepted_true = 0
    null_alarms = nulls = 0
    for r in results:
        if "crashed" in r:
            continue
        accepted = [members(a) for a in r["accepted"]]
        truth = set(r["truth"])
        true_total += len(truth)
        found += sum(1 for t in truth if any(t in a for a in accepted))
        accepted_total += len(accepted)
        accepted_true += sum(1 for a in accepted if a & truth)
        if not truth:
            nulls += 1
            null_alarms += bool(accepted)
    ok = [r for r in results if "crashed" not in r]
    walls = [r["wall_s"] for r in ok]
    return {
        "machines": len(results),
        "crashed": len(results) - len(ok),
        "recall": found / true_total if true_total else float("nan"),
        "precision": accepted_true / accepted_total if accepted_total else float("nan"),
        "null_machines": nulls,
        "null_alarms": null_alarms,
        "median_reduction": statistics.median(r["reduction"] for r in ok) if ok else float("nan"),
        "machines_with_a_swap": sum(1 for r in ok if r.get("swaps")),
        "median_wall_s": statistics.median(walls) if walls else float("nan"),
        "max_wall_s": max(walls) if walls else float("nan"),
        "by_effect_count": {
            n: {
                "machines": len(group),
                "median_wall_s": statistics.median(r["wall_s"] for r in group),
                "median_cpu_s": statistics.median(r.get("cpu_s", math.nan) for r in group),
                "median_load": statistics.median(r.get("load", math.nan) for r in group),
            }
            for n in EFFECT_COUNTS
            if (group := [r for r in ok if len(r["truth"]) == n])
        },
    }


def where_time_goes(results: list[dict]) -> str:
    """Per phase of the selection: wall time, tasks and replays summed over the machines."""
    totals: dict[str, Counter] = defaultdict(Counter)
    diagnosis_wall = 0.0
    for r in results:
        diagnosis_wall += r.get("diagnosis_wall_s") or 0.0
        for phase, figures in r.get("time", {}).items():
            totals[phase].update(figures)
    selection = totals.pop("total", Counter())
    totals.pop("diagnosis", None)  # the parent's CPU and the idle-wall estimate: not a phase
    lines = ["| phase | wall [s] | share of the diagnoses' wall | tasks | replays |"]
    lines.append("|---|---|---|---|---|")
    rows = [*totals.items(), ("selection (all phases)", selection)]
    rows.append(("outside the selection", Counter(wall_s=diagnosis_wall - selection["wall_s"])))
    for phase, f in rows:
        share = f["wall_s"] / diagnosis_wall if diagnosis_wall else math.nan
        lines.append(
            f"| {phase} | {f['wall_s']:.0f} | {100 * share:.0f} % | {f['tasks']} | {f['replays']} |"
        )
    return "\n".join(lines)


def confusion(results: list[dict]) -> str:
    """Per true effect: how often it was found, and what was accepted on its machines."""
    found, seen, beside = Counter(), Counter(), defaultdict(Counter)
    for r in results:
        if "crashed" in r:
            continue
        accepted = [members(a) for a in r["accepted"]]
        for t in r["truth"] or ["(none)"]:
            seen[t] += 1
            found[t] += any(t in a for a in accepted)
            for a in r["accepted"]:
                label = "{" + ", ".join(sorted(a)) + "}" if isinstance(a, list) else a
                beside[t][label] += 1
    lines = ["| true effect | machines | found | accepted on its machines |", "|---|---|---|---|"]
    for t in sorted(seen):
        others = ", ".join(f"{k} {v}" for k, v in beside[t].most_common())
        lines.append(f"| {t} | {seen[t]} | {found[t]} | {others or 'nothing'} |")
    return "\n".join(lines)


def seeds(text: str) -> list[int]:
    """``A-B`` (inclusive), a comma list, or ``none``."""
    if text == "none":
        return []
    if "-" in text:
        low, high = (int(x) for x in text.split("-"))
        return list(range(low, high + 1))
    return [int(x) for x in text.split(",") if x]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tune", type=seeds, default=seeds("0-19"), help="seeds to choose on")
    parser.add_argument("--report", type=seeds, default=seeds("100-159"), help="seeds to report")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", default="out/random-machines")
    parser.add_argument(
        "--score", action="store_true", help="only score the machines already done (no runs)"
    )
    args = parser.parse_args()
    if set(args.tune) & set(args.report):
        parser.error("--tune and --report seeds must be disjoint")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "results.jsonl"
    done = {}
    if log.exists():
        for line in log.read_text().splitlines():
            entry = json.loads(line)
            done[entry["seed"]] = entry
    for seed in args.tune + args.report:
        if seed in done or args.score:
            continue
        result = run_machine(machine_of(seed), out / f"machine{seed}", args.workers)
        done[seed] = result
        with log.open("a") as stream:
            stream.write(json.dumps(result) + "\n")
        mark = "CRASH" if "crashed" in result else f"accepted {result['accepted'] or 'nothing'}"
        print(f"seed {seed}: truth {result.get('truth', [])}; {mark} ({result['wall_s']:.0f} s)")
    for label, chosen in (("tune", args.tune), ("report", args.report)):
        results = [done[s] for s in chosen if s in done]
        if results:
            figures = score(results)
            print(f"\n{label} seeds ({len(results)} of {len(chosen)} done): " + json.dumps(figures))
    report = [done[s] for s in args.report if s in done]
    print("\nReport seeds, per true effect:\n" + confusion(report))
    print("\nReport seeds, where the time goes:\n" + where_time_goes(report))


if __name__ == "__main__":
    main()
