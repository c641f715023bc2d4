"""Twin-to-machine transfer: do gains tuned on the calibrated twin work better on the machine?

For each virtual machine (two or three effects of the library at seeded random sizes, plus a
calibration error of up to ``--perturb`` on the calibrated parameters), all through the command
line:

1. ``twin synth scenarios/diagnosis.yaml`` with the machine's effects: the excitation run;
2. ``twin diagnose`` on it: ``plant.yaml`` (the calibrated plant);
3. ``twin optimize`` on the production trajectory (``--scenario``, reference 1 by default),
   on the nominal twin (once for all machines) and on the calibrated twin (``--plant-parameters``),
   same method, budget and seed; with ``--oracle`` also on the machine itself (the best a tuning
   on this trajectory can reach);
4. ``twin simulate --machine`` judges each set on the machine: E_pk there beside each twin's
   prediction of it, and for the calibrated twin the prediction's interval over what the
   diagnosis left uncertain (the intervals of ``plant.yaml``), widened by what the calibrated
   twin still missed on the held-out runs (its ``model_error``), and whether the machine's
   E_pk lies inside it.

The campaign on the calibrated twin is robust over the intervals of ``plant.yaml`` (the
default of ``twin optimize --plant-parameters`` for a file with intervals); ``--no-robust``
tunes on the calibrated plant alone (``--samples 1``). ``--effect NAME:...`` (repeatable, as
``twin synth`` takes it) judges one machine of these effects instead of drawn ones (seed
``--synth-seed``).

The machine is a plant parameter file holding the virtual machine's true parameters (what
``twin synth`` set). Results are appended to ``<out>/results.jsonl`` as they come (an interrupted
benchmark resumes); the report prints the per-machine table, the medians and the goal figures,
and draws ``<out>/transfer.png``.

    python benchmarks/transfer.py [--machines 5] [--method cmaes] [--budget 240] [--workers 2]
                                  [--oracle] [--no-robust] [--effect NAME:...] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
EXCITATION = ROOT / "scenarios" / "diagnosis.yaml"
# Effects and their size ranges (twin synth parameters); a machine draws EFFECTS_PER_MACHINE of
# them.
EFFECT_RANGES = {
    "stribeck": {"stribeck_friction": (0.1, 0.3), "stribeck_speed": (0.3, 0.7)},
    "coulomb_change": {"delta_coulomb": (0.05, 0.2)},
    "backlash_change": {"delta_backlash": (3e-6, 10e-6)},
    "torque_ripple": {"ripple_amplitude": (0.02, 0.08), "ripple_order": (6.0, 6.0)},
    "asymmetric_friction": {"coulomb_asymmetry": (0.04, 0.15)},
    "inertia_change": {"relative_change": (0.08, 0.3)},
    "current_lag": {"current_time_constant": (1.5e-4, 5e-4)},
}
EFFECTS_PER_MACHINE = (2, 3)  # a machine draws two or three effects


def twin(*args: str) -> dict:
    """Run ``twin ARGS --json``-style commands; returns the parsed JSON of the last line."""
    command = [sys.executable, "-m", "twin_cosim", *args]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr}")
    lines = done.stdout.strip().splitlines()
    return json.loads(lines[-1]) if lines and lines[-1].startswith("{") else {}


def draw_machine(index: int, seed: int) -> dict:
    """The effects of machine ``index``: names and sizes drawn from a seeded generator."""
    rng = np.random.default_rng([seed, index])
    count = int(rng.choice(EFFECTS_PER_MACHINE))
    names = rng.choice(sorted(EFFECT_RANGES), size=count, replace=False)
    effects = []
    for name in sorted(names):
        params = {p: float(rng.uniform(lo, hi)) for p, (lo, hi) in EFFECT_RANGES[name].items()}
        effects.append(f"{name}:" + ",".join(f"{p}={v:.4g}" for p, v in params.items()))
    return {"machine": index, "effects": effects, "synth_seed": 1000 * seed + index}


def optimize(scenario: Path, out: Path, args: argparse.Namespace, *extra: str) -> dict:
    """A campaign (reused when its result exists)."""
    if (out / "result.json").exists():
        return json.loads((out / "result.json").read_text())
    resume = ["--resume", str(out)] if (out / "campaign.json").exists() else ["--out", str(out)]
    twin(
        "optimize",
        str(scenario),
        "--method",
        args.method,
        "--budget",
        str(args.budget),
        "--seed",
        str(args.seed),
        "--workers",
        str(args.workers),
        "--quiet",
        "--json",
        *resume,
        *extra,
    )
    return json.loads((out / "result.json").read_text())


def judge(scenario: Path, params: Path, machine: Path, out: Path, *extra: str) -> dict:
    """E_pk, ITAE, IAU of a set on the machine beside the twin's prediction."""
    summary = twin(
        "simulate",
        str(scenario),
        "--params",
        str(params),
        "--machine",
        str(machine),
        "--out",
        str(out),
        "--json",
        *extra,
    )
    return summary["machine"]


def run_machine(case: dict, nominal: Path, args: argparse.Namespace) -> dict:
    folder = Path(args.out) / f"machine{case['machine']}"
    folder.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    run = folder / "excitation.csv"
    synth = ["synth", str(EXCITATION), "--perturb", str(args.perturb), "--out", str(run)]
    synth += ["--seed", str(case["synth_seed"])]
    for effect in case["effects"]:
        synth += ["--effect", effect]
    twin(*synth)
    truth = json.loads(run.with_name(run.name + ".truth.json").read_text())
    machine = folder / "machine.yaml"
    machine.write_text(
        yaml.safe_dump(
            {
                "model": "drive2mass",
                "parameters": truth["plant_parameters"],
                "provenance": {
                    name: {"source": "twin synth (the virtual machine's true value)"}
                    for name in truth["plant_parameters"]
                },
                "created_by": {"command": "benchmarks/transfer.py", "effects": case["effects"]},
            },
            sort_keys=False,
        )
    )
    diagnosis = folder / "diagnosis"
    if not (diagnosis / "plant.yaml").exists():
        twin(
            "diagnose",
            str(EXCITATION),
            "--measured",
            str(run),
            "--out",
            str(diagnosis),
            "--workers",
            str(args.workers),
            "--json",
        )
    plant = diagnosis / "plant.yaml"
    accepted = json.loads((diagnosis / "diagnosis.json").read_text())["accepted"]
    scenario = Path(args.scenario)
    robust = ["--samples", "1"] if args.no_robust else []
    optimize(scenario, folder / "calibrated", args, "--plant-parameters", str(plant), *robust)
    sets = {
        "nominal": judge(scenario, nominal / "result.json", machine, folder / "judge-nominal"),
        "calibrated": judge(
            scenario,
            folder / "calibrated" / "result.json",
            machine,
            folder / "judge-calibrated",
            "--plant-parameters",
            str(plant),
        ),
        "fine_tune": judge(scenario, Path("ft"), machine, folder / "judge-ft"),
    }
    if args.oracle:
        optimize(scenario, folder / "oracle", args, "--plant-parameters", str(machine))
        sets["oracle"] = judge(
            scenario, folder / "oracle" / "result.json", machine, folder / "judge-oracle"
        )
    return {
        **case,
        "accepted": accepted,
        "plant_yaml": yaml.safe_load(plant.read_text())["parameters"],
        "judged": sets,
        "wall_s": time.perf_counter() - start,
    }


SET_LABELS = {
    "fine_tune": "FT (the paper's set)",
    "nominal": "tuned on the nominal twin",
    "calibrated": "tuned on the calibrated twin",
    "oracle": "tuned on the machine (oracle)",
}


def report(results: list[dict], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    print(
        "\nmachine | effects | accepted | E_pk on machine [um]: FT, nominal-tuned, "
        "calibrated-tuned(, oracle) | twin prediction error of E_pk: nominal, calibrated"
    )
    improvements, errors_cal, errors_nom = [], [], []
    for r in results:
        j = r["judged"]
        e = {k: v["E_pk_um"]["machine"] for k, v in j.items()}
        pred_nom = j["nominal"]["E_pk_um"]["relative_error_pct"]
        pred_cal = j["calibrated"]["E_pk_um"]["relative_error_pct"]
        improvements.append(1.0 - e["calibrated"] / e["nominal"])
        errors_cal.append(abs(pred_cal))
        errors_nom.append(abs(pred_nom))
        oracle = f", {e['oracle']:.2f}" if "oracle" in e else ""
        interval = j["calibrated"]["E_pk_um"]
        margin = interval.get("margin", 0.0)
        held_out = f", of it +/- {margin:.2f} um the twin's held-out error" if margin else ""
        stated = (
            f" (interval {interval['low']:.2f}-{interval['high']:.2f} um{held_out}: "
            f"{'inside' if interval['inside'] else 'outside'})"
            if "inside" in interval
            else ""
        )
        print(
            f"{r['machine']} | {'; '.join(r['effects'])} | {r['accepted']} | "
            f"{e['fine_tune']:.2f}, {e['nominal']:.2f}, {e['calibrated']:.2f}{oracle} | "
            f"{pred_nom:+.1f} %, {pred_cal:+.1f} %{stated}"
        )
    median_gain = statistics.median(improvements)
    print(
        f"\nmedian E_pk reduction on the machine, calibrated vs nominal twin: {median_gain:.1%} "
        f"(goal >= 30 %: {'met' if median_gain >= 0.3 else 'not met'})"
    )
    print(
        f"|prediction error| of E_pk, calibrated twin: median {statistics.median(errors_cal):.1f} "
        f"%, max {max(errors_cal):.1f} % (goal <= 10 %: "
        f"{'met' if max(errors_cal) <= 10 else 'not met'} on all machines, "
        f"{sum(e <= 10 for e in errors_cal)}/{len(errors_cal)} machines); nominal twin: median "
        f"{statistics.median(errors_nom):.1f} %"
    )
    stated = [r["judged"]["calibrated"]["E_pk_um"] for r in results]
    stated = [e for e in stated if "inside" in e]
    if stated:
        inside = sum(e["inside"] for e in stated)
        print(
            f"the machine's E_pk inside the calibrated twin's stated interval on {inside}/"
            f"{len(stated)} machines (goal: all): "
            + ", ".join(f"{e['low']:.2f}-{e['high']:.2f} um" for e in stated)
        )
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5))
    index = np.arange(len(results))
    labels = [f"M{r['machine']}" for r in results]
    keys = ["fine_tune", "nominal", "calibrated"] + (
        ["oracle"] if "oracle" in results[0]["judged"] else []
    )
    width = 0.8 / len(keys)
    for k, key in enumerate(keys):
        values = [r["judged"][key]["E_pk_um"]["machine"] for r in results]
        left.bar(index + k * width, values, width, label=SET_LABELS[key])
    left.set_xticks(index + 0.4 - width / 2, labels)
    left.set_ylabel("E_pk on the machine [um]")
    left.set_title("Gains judged on the machine")
    for key in ("nominal", "calibrated"):
        values = [r["judged"][key]["E_pk_um"]["relative_error_pct"] for r in results]
        right.plot(labels, values, "o-", label=f"{key} twin")
    stated = [r["judged"]["calibrated"]["E_pk_um"] for r in results]
    if all("low" in e for e in stated):  # the calibrated twin's interval, as errors too
        errors = [
            [100 * (e["twin"] - e["low"]) / e["machine"] for e in stated],
            [100 * (e["high"] - e["twin"]) / e["machine"] for e in stated],
        ]
        centre = [e["relative_error_pct"] for e in stated]
        right.errorbar(labels, centre, yerr=errors, fmt="none", color="tab:orange", capsize=4)
        right.plot([], [], "|", color="tab:orange", label="calibrated twin's stated interval")
    right.axhline(0.0, color="k", lw=0.8)
    right.axhspan(-10, 10, color="0.9", label="+/- 10 %")
    right.set_ylabel("twin's E_pk prediction error [%]")
    right.set_title("Prediction of the machine's E_pk (own tuned set)")
    for ax in (left, right):  # below the axes: a legend inside covers bars or points
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=2, fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "transfer.png", dpi=110)
    print(f"wrote {out / 'transfer.png'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--machines", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0, help="seed of the machines and campaigns")
    parser.add_argument("--perturb", type=float, default=0.02)
    parser.add_argument("--method", default="cmaes")
    parser.add_argument("--budget", type=int, default=240)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default=str(ROOT / "scenarios" / "reference1.yaml"))
    parser.add_argument("--oracle", action="store_true", help="also tune on the machine itself")
    parser.add_argument(
        "--no-robust",
        action="store_true",
        help="tune on the calibrated plant alone (default: robust over plant.yaml's intervals)",
    )
    parser.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME:param=value,...",
        help="one machine of these effects (repeatable, as twin synth takes them) instead of "
        "--machines drawn ones",
    )
    parser.add_argument("--synth-seed", type=int, default=1, help="seed of an --effect machine")
    parser.add_argument("--out", default="out/transfer")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"load average at start: {os.getloadavg()}", flush=True)
    path = out / "results.jsonl"
    done = [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []
    nominal = out / "nominal"
    optimize(Path(args.scenario), nominal, args)
    cases = (
        [{"machine": 0, "effects": args.effect, "synth_seed": args.synth_seed}]
        if args.effect
        else [draw_machine(index, args.seed) for index in range(args.machines)]
    )
    for case in cases:
        index = case["machine"]
        if any(r["machine"] == index for r in done):
            continue
        result = run_machine(case, nominal, args)
        done.append(result)
        with path.open("a") as stream:
            stream.write(json.dumps(result) + "\n")
        print(
            f"machine {index}: {result['effects']} -> accepted {result['accepted']} "
            f"({result['wall_s']:.0f} s)",
            flush=True,
        )
    print(f"load average at end: {os.getloadavg()}")
    report(sorted(done, key=lambda r: r["machine"]), out)


if __name__ == "__main__":
    main()
