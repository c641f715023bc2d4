"""Robust tuning and exact early stopping: what they buy and what they cost, in one run.

Per seed, campaigns of one method (CE by default; nominal twin), all through ``twin optimize``:

- ``ref1-full``: reference 1 alone, every run to the end (``--no-early-stop``);
- ``ref1``: reference 1 alone with early stopping (must end exactly where ``ref1-full`` does);
- ``robust``: reference 1 and ``scenarios/diagnosis.yaml`` x ``--samples`` plant samples within
  ``--tolerance`` of the calibrated parameters, worst case (``--objective``), early stopping;
  with ``--relative`` the runs' E_pk relative to Fine-Tune's on the same case;
- per held-out scenario (``--holdout``, reference 2 by default, and ``--random N`` trajectories
  drawn at random within the envelope of the shipped ones: speeds up to 120 mm/s, accelerations
  0.02 to 1 m/s^2, reversals while moving and after dwells): a campaign on it, early stopping on
  (the target of the transfer).

Early stopping is exact for CE only: with another ``--method`` it is off and ``ref1`` is
``ref1-full``. Then every tuned set (and Fine-Tune) is judged on each held-out scenario with
``twin simulate``. Prints per seed the cost (evaluations, simulated speed-loop steps, wall time)
and the goal figures (with what of each held-out trajectory's motion lies beyond that of the
tuning ones, :mod:`twin_cosim.reference`), and the medians over the seeds; writes
``<out>/robust.json``. The machine's load average is printed at start and end. Simulated steps
are the cost measure that the machine's load does not blur.

    python benchmarks/robust.py [--method ce] [--seeds 0,1,2] [--budget 300] [--samples 4]
                                [--tolerance 0.03] [--objective worst] [--relative]
                                [--holdout reference2.yaml ...] [--random N] [--workers 1]
                                [--out out/robust]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml

from twin_cosim.reference import envelope_of, outside
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"


def twin(*args: str) -> str:
    command = [sys.executable, "-m", "twin_cosim", *args]
    done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(args)}: {done.stderr}")
    return done.stdout


def campaign(out: Path, scenarios: list[Path], extra: list[str], args, seed: int) -> dict:
    """Run (or reuse) one campaign; returns its result with the simulated steps added."""
    if not (out / "result.json").exists():
        where = ["--resume", str(out)] if (out / "campaign.json").exists() else ["--out", str(out)]
        twin(
            "optimize",
            *map(str, scenarios),
            "--method",
            args.method,
            "--seed",
            str(seed),
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
    return result


STOP_ACCELERATION = 0.2  # m/s^2 of the stops of a random trajectory


def _stop(speed: float) -> dict:
    """A ramp from ``speed`` (m/s) to standstill at STOP_ACCELERATION, 10 ms held."""
    duration = abs(speed) / STOP_ACCELERATION + 0.01
    return {
        "ramp": {"velocity": 0.0, "acceleration": STOP_ACCELERATION, "duration": round(duration, 3)}
    }


def random_trajectory(seed: int, path: Path) -> Path:
    """Write a seeded random production trajectory (about 6 to 12 s) as a scenario file.

    Six moves, each to a speed of 5 to 120 mm/s in either direction at an acceleration of
    0.02 to 1 m/s^2 (log-uniform, raised where the change would take over 1.5 s), held 0.2 to
    0.6 s; a third of them end in a stop and a dwell, so that reversals come both while moving and
    after dwells. A stop and a dwell at the end.
    """
    rng = np.random.default_rng(seed)
    segments: list[dict] = [{"dwell": 0.2}]
    speed = 0.0
    for _ in range(6):
        target = float(rng.uniform(0.005, 0.12) * rng.choice([-1.0, 1.0]))
        acceleration = max(float(np.exp(rng.uniform(np.log(0.02), 0.0))), abs(target - speed) / 1.5)
        hold = float(rng.uniform(0.2, 0.6))
        ramp = {"velocity": round(target, 4), "acceleration": round(acceleration, 3)}
        segments.append(
            {"ramp": {**ramp, "duration": round(abs(target - speed) / acceleration + hold, 3)}}
        )
        speed = target
        if rng.uniform() < 1.0 / 3.0:
            segments.append(_stop(speed))
            segments.append({"dwell": round(float(rng.uniform(0.1, 0.3)), 3)})
            speed = 0.0
    segments += [_stop(speed), {"dwell": 0.2}]
    scenario = {
        "name": path.stem,
        "description": f"random production trajectory, seed {seed} (benchmarks/robust.py)",
        "controller": {"parameters": "ft"},
        "reference": {"sample_period": 0.004, "start_position": 0.0, "segments": segments},
        "run": {"metrics_window": [0.0, None]},
    }
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    return path


def epk_on(scenario: Path, params: str, out: Path) -> float:
    """E_pk (um) of a set on a scenario (nominal twin)."""
    twin("simulate", str(scenario), "--params", params, "--out", str(out))
    return json.loads((out / "summary.json").read_text())["metrics"]["E_pk_um"]


def run_seed(seed: int, args) -> dict:
    """The campaigns of one seed and their sets judged on the held-out scenarios."""
    out = Path(args.out) / f"seed{seed}"
    ref1 = SCENARIOS / "reference1.yaml"
    pair = [ref1, SCENARIOS / "diagnosis.yaml"]
    robust = ["--samples", str(args.samples), "--tolerance", str(args.tolerance)]
    robust += ["--objective", args.objective] + (["--relative"] if args.relative else [])
    runs = {"ref1-full": campaign(out / "ref1-full", [ref1], ["--no-early-stop"], args, seed)}
    exact = args.method == "ce"
    runs["ref1"] = campaign(out / "ref1", [ref1], [], args, seed) if exact else runs["ref1-full"]
    runs["robust"] = campaign(out / "robust", pair, robust, args, seed)
    holdouts = [Path(h) if Path(h).is_file() else SCENARIOS / h for h in args.holdout]
    holdouts += [
        random_trajectory(1000 + k, Path(args.out) / f"random{k}.yaml") for k in range(args.random)
    ]
    for holdout in holdouts:
        runs[holdout.stem] = campaign(out / holdout.stem, [holdout], [], args, seed)
    judged = {}
    for holdout in holdouts:
        judged[holdout.stem] = {"FT": epk_on(holdout, "ft", out / f"judge-{holdout.stem}-FT")}
        for name in ("ref1", "robust", holdout.stem):
            result = str(Path(runs[name]["out_dir"]) / "result.json")
            judged[holdout.stem][name] = epk_on(
                holdout, result, out / f"judge-{holdout.stem}-{name}"
            )
    tuned_on = [envelope_of(load_scenario(p).reference) for p in pair]
    beyond = {h.stem: outside(envelope_of(load_scenario(h).reference), tuned_on) for h in holdouts}
    full, early = runs["ref1-full"], runs["ref1"]
    return {
        "seed": seed,
        "campaigns": runs,
        "judged": judged,
        "beyond_tuning_motion": beyond,
        "same_with_early_stop": full["best_params"] == early["best_params"]
        and full["fitness"] == early["fitness"],
        "robust_steps_vs_full": runs["robust"]["steps"] / full["steps"],
        "robust_steps_vs_early": runs["robust"]["steps"] / early["steps"],
        "robust_wall_vs_early": runs["robust"]["wall_s"] / early["wall_s"],
        "robust_vs_itself": {h: judged[h]["robust"] / judged[h][h] - 1.0 for h in judged},
        "ref1_vs_itself": {h: judged[h]["ref1"] / judged[h][h] - 1.0 for h in judged},
    }


def print_seed(r: dict) -> None:
    print(f"\nseed {r['seed']}: campaign | evaluations | stopped early | steps | wall [s] | best")
    for name, c in r["campaigns"].items():
        print(
            f"  {name} | {c['evaluations']} | {c['stopped']} | {c['steps']:.3e} | "
            f"{c['wall_s']:.1f} | {c['fitness']:.3f}"
        )
    print(
        f"  early stopping on reference 1: same result {r['same_with_early_stop']}; robust "
        f"campaign: {r['robust_steps_vs_early']:.2f} x the steps of the single-scenario campaign "
        f"with early stopping ({r['robust_wall_vs_early']:.2f} x its wall time), "
        f"{r['robust_steps_vs_full']:.2f} x the steps of it run to the end"
    )
    for h, values in r["judged"].items():
        print(
            f"  E_pk on {h} [um]: "
            + ", ".join(f"{k} {v:.3f}" for k, v in values.items())
            + f"; robust {r['robust_vs_itself'][h]:+.1%}, reference-1 set "
            f"{r['ref1_vs_itself'][h]:+.1%} from the set tuned on {h} itself; beyond the tuning "
            f"motion: {'; '.join(r['beyond_tuning_motion'][h]) or 'nothing'}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--method", default="ce", help="ce (early stopping exact) or another")
    parser.add_argument("--seeds", default="0", help="comma-separated campaign seeds")
    parser.add_argument("--budget", type=int, default=300)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--tolerance", type=float, default=0.03)
    parser.add_argument("--objective", default="worst", choices=["worst", "mean"])
    parser.add_argument("--relative", action="store_true")
    parser.add_argument("--holdout", nargs="+", default=["reference2.yaml"])
    parser.add_argument("--random", type=int, default=0, help="random held-out trajectories")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default="out/robust")
    args = parser.parse_args()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    print(f"load average at start: {os.getloadavg()}", flush=True)
    results = []
    for seed in (int(s) for s in args.seeds.split(",")):
        results.append(run_seed(seed, args))
        print_seed(results[-1])
    print(f"\nload average at end: {os.getloadavg()}")
    cost = statistics.median(r["robust_steps_vs_early"] for r in results)
    print(
        f"median over {len(results)} seeds: robust campaign {cost:.2f} x the simulated steps of "
        f"the single-scenario campaign (goal < 8 x: {'met' if cost < 8 else 'not met'})"
    )
    for h in results[0]["judged"]:
        gap = statistics.median(r["robust_vs_itself"][h] for r in results)
        print(
            f"median robust set on {h}: {gap:+.1%} from tuning on {h} itself (goal within 15 %: "
            f"{'met' if gap <= 0.15 else 'not met'}); reference-1 set "
            f"{statistics.median(r['ref1_vs_itself'][h] for r in results):+.1%}"
        )
    (Path(args.out) / "robust.json").write_text(
        json.dumps({"seeds": results, "args": vars(args)}, indent=2)
    )


if __name__ == "__main__":
    main()
