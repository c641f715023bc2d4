"""The gap diagnosis judged as a detector on seeded random virtual machines and trajectories.

Each machine (``machine_of``) has 0 to 3 effects of the drive2mass library at random moderate
sizes and signs (pairs and triples that share a regime are drawn more often, e.g. Stribeck with
Coulomb and backlash), a calibration error of up to 2 % on every calibrated parameter, its own
noise seed, and one excitation: by default a random trajectory of the kind a user writes
(``twin synth --random-excitation``: moves, creeps, speed levels reversing while moving,
oscillations and dwells at random sizes and speeds within the axis' limits, each half of the
time split covering every regime; :func:`twin_cosim.gap.synth.random_excitation`), drawn from
``--trajectories`` trajectories of the machine's seed set: tune machines follow tune
trajectories (seeds 0, 1, ...), report machines report trajectories (seeds 1000, 1001, ...),
so nothing of the report seeds, machines or trajectories, is seen while tuning. With
``--excitation diagnosis`` (or ``sweep``) every machine follows that shipped scenario instead.
For each machine, through the command line: ``twin synth`` makes the measured run, ``twin
diagnose`` (time split) says what it finds. Scored per machine:

- recall: true effects accepted (an accepted look-alike group that holds the truth counts);
- precision: accepted effects (or groups) that hold a true effect;
- null machines (no effect) with anything accepted;
- the held-out reduction of the normalised RMS by the final model, the wall time;

and reported per set (tune, report), per trajectory and per true effect. Results are appended
to ``<out>/results.jsonl`` as they come (an interrupted run resumes)::

    python benchmarks/random_machines.py --tune 0-39 --report 100-159 [--excitation random]
                                         [--trajectories 4] [--workers 2] [--out DIR]
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

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = {
    "diagnosis": ROOT / "scenarios" / "diagnosis.yaml",
    "sweep": ROOT / "scenarios" / "sweep.yaml",
}
# Plant and controller of the random trajectories (their reference is replaced)
RANDOM_BASE = SHIPPED["diagnosis"]
# First trajectory seed of each set: tune machines follow tune trajectories, report machines
# report trajectories.
TRAJECTORY_SEEDS = {"tune": 0, "report": 1000}
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


def machine_of(seed: int, trajectories: list[int]) -> dict:
    """The machine of a seed: effects and the seed of its trajectory (one of ``trajectories``)."""
    rng = np.random.default_rng([7919, seed])
    effects = draw_effects(rng)
    return {"seed": seed, "effects": effects, "trajectory": int(rng.choice(trajectories))}


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
    run = folder / "run.csv"
    synth = ["synth", "--perturb", str(PERTURB), "--seed", str(case["seed"])]
    if case["excitation"] == "random":
        synth += [str(RANDOM_BASE), "--random-excitation", str(case["trajectory"])]
        scenario = run.with_name(run.name + ".scenario.yaml")
    else:
        scenario = SHIPPED[case["excitation"]]
        synth += [str(scenario)]
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
    truth = truth_names(case["effects"])
    if diagnosed.returncode != 0:
        crash = diagnosed.stderr[-2000:]
        return {**case, "truth": truth, "crashed": crash, "wall_s": wall, "cpu_s": cpu}
    summary = json.loads(diagnosed.stdout)
    rounds = summary["rounds"]
    remaining = summary["gap"]["remaining"]  # the final model's (after swaps, backward pass)
    before, after = remaining["normalised_rms_before"], remaining["times_noise_floor"]
    return {
        **case,
        "truth": truth,
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


def tally(results: list[dict]) -> dict:
    """Recall, precision and null alarms of some machines (crashed ones left out), with their
    counts."""
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
    return {
        "recall": found / true_total if true_total else float("nan"),
        "found": found,
        "true_effects": true_total,
        "precision": accepted_true / accepted_total if accepted_total else float("nan"),
        "accepted_true": accepted_true,
        "accepted": accepted_total,
        "null_machines": nulls,
        "null_alarms": null_alarms,
    }


def score(results: list[dict]) -> dict:
    """Recall, precision, null false alarms, reductions and wall times of a set of machines."""
    ok = [r for r in results if "crashed" not in r]
    walls = [r["wall_s"] for r in ok]
    return {
        "machines": len(results),
        "crashed": len(results) - len(ok),
        **tally(results),
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


def trajectory_label(r: dict) -> str:
    """The excitation a machine followed: ``random 1002`` or a shipped scenario's name."""
    return f"random {r['trajectory']}" if r["excitation"] == "random" else r["excitation"]


def by_trajectory(results: list[dict]) -> str:
    """Per trajectory: machines, recall, precision and null alarms (a Markdown table)."""
    groups: dict[str, list[dict]] = defaultdict(list)
    for r in results:
        groups[trajectory_label(r)].append(r)
    lines = [
        "| trajectory | machines | recall | precision | null machines with an effect accepted |",
        "|---|---|---|---|---|",
    ]
    for label in sorted(groups):
        t = tally(groups[label])
        lines.append(
            f"| {label} | {len(groups[label])} | {t['recall']:.2f} ({t['found']}/"
            f"{t['true_effects']}) | {t['precision']:.2f} ({t['accepted_true']}/{t['accepted']}) "
            f"| {t['null_alarms']}/{t['null_machines']} |"
        )
    return "\n".join(lines)


def misses(results: list[dict]) -> str:
    """The machines with a true effect missed or a wrong one accepted (a Markdown table)."""
    lines = [
        "| seed | trajectory | effects | accepted | missed | wrong |",
        "|---|---|---|---|---|---|",
    ]
    for r in sorted(results, key=lambda r: r["seed"]):
        if "crashed" in r:
            lines.append(f"| {r['seed']} | {trajectory_label(r)} | crashed | | | |")
            continue
        accepted = [members(a) for a in r["accepted"]]
        missed = [t for t in r["truth"] if not any(t in a for a in accepted)]
        wrong = [a for a in r["accepted"] if not members(a) & set(r["truth"])]
        if missed or wrong:
            shown = "; ".join(e.replace(",", ", ") for e in r["effects"]) or "none"
            lines.append(
                f"| {r['seed']} | {trajectory_label(r)} | {shown} | {r['accepted'] or 'nothing'} "
                f"| {', '.join(missed) or '-'} | {wrong or '-'} |"
            )
    return "\n".join(lines)


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
    lines = [
        "| true effect | machines | found | recall | accepted on its machines |",
        "|---|---|---|---|---|",
    ]
    for t in sorted(seen):
        others = ", ".join(f"{k} {v}" for k, v in beside[t].most_common())
        recall = "-" if t == "(none)" else f"{found[t] / seen[t]:.2f}"
        lines.append(f"| {t} | {seen[t]} | {found[t]} | {recall} | {others or 'nothing'} |")
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
    parser.add_argument("--tune", type=seeds, default=seeds("0-39"), help="seeds to choose on")
    parser.add_argument("--report", type=seeds, default=seeds("100-159"), help="seeds to report")
    parser.add_argument(
        "--excitation",
        choices=["random", *SHIPPED],
        default="random",
        help="random trajectories of the seed set (default), or a shipped scenario for all",
    )
    parser.add_argument(
        "--trajectories", type=int, default=4, help="random trajectories per seed set"
    )
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
    sets = {"tune": args.tune, "report": args.report}
    for label, chosen in sets.items():
        first = TRAJECTORY_SEEDS[label]
        trajectories = list(range(first, first + args.trajectories))
        for seed in chosen:
            if seed in done or args.score:
                continue
            case = {**machine_of(seed, trajectories), "excitation": args.excitation}
            result = run_machine(case, out / f"machine{seed}", args.workers)
            done[seed] = result
            with log.open("a") as stream:
                stream.write(json.dumps(result) + "\n")
            mark = "CRASH" if "crashed" in result else f"accepted {result['accepted'] or 'nothing'}"
            print(
                f"seed {seed} ({trajectory_label(result)}): truth {result['truth']}; {mark} "
                f"({result['wall_s']:.0f} s)",
                flush=True,
            )
    for label, chosen in sets.items():
        results = [done[s] for s in chosen if s in done]
        if not results:
            continue
        print(
            f"\n{label} seeds ({len(results)} of {len(chosen)} done): " + json.dumps(score(results))
        )
        print(f"\n{label} seeds, per trajectory:\n" + by_trajectory(results))
        print(f"\n{label} seeds, per true effect:\n" + confusion(results))
        print(f"\n{label} seeds, misses and wrong effects:\n" + misses(results))
    report = [done[s] for s in args.report if s in done]
    if report:
        print("\nReport seeds, where the time goes:\n" + where_time_goes(report))


if __name__ == "__main__":
    main()
