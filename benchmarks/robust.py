"""Robust tuning and exact early stopping: what they buy and what they cost, in one run.

Campaigns (CE by default, the same seed and budget; nominal twin), all through ``twin optimize``
(with another ``--method``, early stopping is off and ``ref1`` is ``ref1-full``):

- ``ref1-full``: reference 1 alone, every run to the end (``--no-early-stop``);
- ``ref1``: reference 1 alone with early stopping (must end exactly where ``ref1-full`` does);
- ``robust``: reference 1 and ``scenarios/diagnosis.yaml`` x ``--samples`` plant samples within
  ``--tolerance`` of the calibrated parameters, worst case, early stopping on;
- ``ref2``: reference 2 itself, early stopping on (the target of the transfer);
- with ``--robust-full`` also the robust campaign without early stopping.

Then every tuned set (and Fine-Tune) is judged on reference 2 with ``twin simulate``. Prints the
cost (evaluations, simulated speed-loop steps, wall time) and the goal figures; writes
``<out>/robust.json``. The machine's load average is printed at start and end.

    python benchmarks/robust.py [--budget 300] [--samples 4] [--tolerance 0.03] [--workers 1]
                                [--out out/robust]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"


def twin(*args: str) -> str:
    command = [sys.executable, "-m", "twin_cosim", *args]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr}")
    return done.stdout


def campaign(name: str, scenarios: list[Path], extra: list[str], args) -> dict:
    """Run (or reuse) one campaign; returns its result with the simulated steps added."""
    out = Path(args.out) / name
    if not (out / "result.json").exists():
        where = ["--resume", str(out)] if (out / "campaign.json").exists() else ["--out", str(out)]
        twin(
            "optimize",
            *map(str, scenarios),
            "--method",
            args.method,
            "--seed",
            str(args.seed),
            "--budget",
            str(args.budget),
            "--workers",
            str(args.workers),
            "--quiet",
            *where,
            *extra,
        )
    result = json.loads((out / "result.json").read_text())
    entries = [json.loads(line) for line in (out / "evaluations.jsonl").read_text().splitlines()]
    result["steps"] = sum(e.get("steps", 0) for e in entries)
    result["stopped"] = sum(e["status"] == "stopped" for e in entries)
    result["logged"] = len(entries)
    return result


def on_reference2(params: str, out: Path) -> float:
    """E_pk (um) of a set on reference 2 (nominal twin)."""
    twin("simulate", str(SCENARIOS / "reference2.yaml"), "--params", params, "--out", str(out))
    return json.loads((out / "summary.json").read_text())["metrics"]["E_pk_um"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", default="ce", help="ce (early stopping exact) or another")
    parser.add_argument("--budget", type=int, default=300)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--tolerance", type=float, default=0.03)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--robust-full", action="store_true")
    parser.add_argument("--out", default="out/robust")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"load average at start: {os.getloadavg()}", flush=True)
    ref1, ref2 = SCENARIOS / "reference1.yaml", SCENARIOS / "reference2.yaml"
    pair = [ref1, SCENARIOS / "diagnosis.yaml"]
    robust = ["--samples", str(args.samples), "--tolerance", str(args.tolerance)]
    runs = {
        "ref1-full": campaign("ref1-full", [ref1], ["--no-early-stop"], args),
        "ref1": campaign("ref1", [ref1], [], args) if args.method == "ce" else None,
        "robust": campaign("robust", pair, robust, args),
        "ref2": campaign("ref2", [ref2], [], args),
    }
    if runs["ref1"] is None:  # no early stopping for this method: the same campaign
        runs["ref1"] = runs["ref1-full"]
    if args.robust_full:
        runs["robust-full"] = campaign("robust-full", pair, [*robust, "--no-early-stop"], args)
    print(f"load average at end of the campaigns: {os.getloadavg()}", flush=True)
    judged = {"FT": on_reference2("ft", out / "judge-FT")}
    for name in runs:
        result = Path(runs[name]["out_dir"]) / "result.json"
        judged[name] = on_reference2(str(result), out / f"judge-{name}")
    full, early = runs["ref1-full"], runs["ref1"]
    same = full["best_params"] == early["best_params"] and full["fitness"] == early["fitness"]
    print("\ncampaign | evaluations | stopped early | simulated steps | wall [s] | best [um]")
    for name, r in runs.items():
        print(
            f"{name} | {r['evaluations']} | {r['stopped']} | {r['steps']:.3e} | "
            f"{r['wall_s']:.1f} | {r['fitness']:.3f}"
        )
    print(
        f"\nearly stopping on reference 1: same result {same}; steps "
        f"{early['steps'] / full['steps']:.2f} x, wall {early['wall_s'] / full['wall_s']:.2f} x "
        "of running every candidate to the end"
    )
    cost_steps = runs["robust"]["steps"] / full["steps"]
    cost_wall = runs["robust"]["wall_s"] / full["wall_s"]
    cost_vs_early = runs["robust"]["wall_s"] / early["wall_s"]
    runs_per_eval = 2 * args.samples
    print(
        f"robust ({2} scenarios x {args.samples} samples = {runs_per_eval} runs per candidate) "
        f"against the single-scenario campaign without early stopping: steps {cost_steps:.2f} x, "
        f"wall {cost_wall:.2f} x; against it with early stopping: wall {cost_vs_early:.2f} x "
        f"(goal < 8 x: {'met' if cost_wall < 8 else 'not met'})"
    )
    print("\nE_pk on reference 2 [um]: " + ", ".join(f"{k} {v:.3f}" for k, v in judged.items()))
    gap = judged["robust"] / judged["ref2"] - 1.0
    print(
        f"robust set on reference 2 is {gap:+.1%} from the set tuned on reference 2 itself "
        f"(goal within 15 %: {'met' if gap <= 0.15 else 'not met'}); reference-1 set: "
        f"{judged['ref1'] / judged['ref2'] - 1.0:+.1%}"
    )
    print(f"load average at end: {os.getloadavg()}")
    (out / "robust.json").write_text(
        json.dumps({"campaigns": runs, "on_reference2": judged, "args": vars(args)}, indent=2)
    )


if __name__ == "__main__":
    main()
