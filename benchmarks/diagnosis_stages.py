"""Where a diagnosis' replays go: per stage and per fit, beside the cost of one replay.

Synthesizes the machines of docs/gap.md "Speed" on ``scenarios/diagnosis.yaml`` (2 %
calibration error, seed 1, the default noise): the single-effect machine (Stribeck friction
0.2 N.m at 0.4 rad/s), the three-effect machine (the same Stribeck curve, backlash +6 um,
Coulomb friction +0.1 N.m) and the null machine (the calibration error alone); each run is
written as CSV and read back, as ``twin synth`` then ``twin diagnose --measured`` do. Then it

1. measures the cost of one replay in this process: the CPU time of a replay of the training
   half (what a fit replays) and of the whole run (what the held-out judging replays), the
   median of ``--repeats``;
2. diagnoses each machine on a pool of ``--workers`` processes and prints, per stage of the
   selection (``time`` of the diagnosis' JSON), the replays asked for, those run and those a
   cache answered, the workers' CPU time, the wall time and its share of the diagnosis' wall,
   and the limit "replays run x CPU per replay / workers" beside the measured wall; per stage
   with fits, the fits' replays, local iterations, and the replays of their starts' searches;
3. with ``--compare``, diagnoses each machine again without the replay caches, in the same
   run, and prints the ratios (replays run, CPU) and whether the decisions and every fitted
   value are the same (they must be: a replay is deterministic);
4. with ``--lean-record``, measures what a lean compiled loop would save: the master compiled
   just in time as it is, against a copy that records only the columns the fits and the
   judging read (t, x, motor_angle, current), replays of the training half in turn (which goes
   first alternates), the median of each and of the rounds' ratios, and checks that the read
   columns are the same.

The wall times follow the machine's load; the replays and the CPU per replay are the robust
figures. Run it at ``nice -n 10`` on shared cores and say the load.

    python benchmarks/diagnosis_stages.py --workers 2 --compare --json stages.json
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from twin_cosim.cosim import run_scenario  # noqa: E402
from twin_cosim.gap.diagnosis import diagnose  # noqa: E402
from twin_cosim.gap.report.pages import summary  # noqa: E402
from twin_cosim.gap.settings import settings_from  # noqa: E402
from twin_cosim.gap.synth import parse_effect, synthesize  # noqa: E402
from twin_cosim.gap.which.replay import cut  # noqa: E402
from twin_cosim.measured import read_measured_csv  # noqa: E402
from twin_cosim.plant import Plant  # noqa: E402
from twin_cosim.scenario import load_scenario  # noqa: E402

SCENARIO = ROOT / "scenarios" / "diagnosis.yaml"
STRIBECK = "stribeck:stribeck_friction=0.2,stribeck_speed=0.4"
MACHINES = {
    "single": [STRIBECK],
    "three": [
        STRIBECK,
        "backlash_change:delta_backlash=6e-6",
        "coulomb_change:delta_coulomb=0.1",
    ],
    "null": [],
}
NOT_STAGES = ("total", "diagnosis")


def replay_cost(repeats: int) -> dict[str, float]:
    """Median CPU time (s) of a replay of the training half and of the whole run of the
    diagnosis scenario on the nominal twin, in this process (after one warm-up replay), and
    the share of the training replay's CPU time spent inside the compiled loop."""
    from twin_cosim import cosim

    scenario = load_scenario(SCENARIO)
    training = cut(scenario, scenario.reference.time[-1] / 2)
    compiled = cosim.compiled_loops
    in_loop: list[float] = []

    def timed_master(*arguments):
        start = time.process_time()
        try:
            return compiled().master(*arguments)
        finally:
            in_loop.append(time.process_time() - start)

    cost = {}
    with Plant(scenario.plant_fmu()) as plant:
        for name, run in (("training_replay_cpu_s", training), ("judging_replay_cpu_s", scenario)):
            run_scenario(plant, run)
            times = []
            for _ in range(repeats):
                start = time.process_time()
                run_scenario(plant, run)
                times.append(time.process_time() - start)
            cost[name] = statistics.median(times)
        cosim.compiled_loops = lambda: SimpleNamespace(master=timed_master)
        try:
            start = time.process_time()
            for _ in range(repeats):
                run_scenario(plant, training)
            whole = time.process_time() - start
        finally:
            cosim.compiled_loops = compiled
    cost["compiled_loop_share"] = sum(in_loop) / whole
    return cost


# The record's columns no fit and no judging reads: the stores a lean loop would leave out.
UNREAD_STORES = (
    "record[a, i, 1] = x_ref[a, i]",
    "record[a, i, 2] = v_ref[a, i]",
    "record[a, i, 4] = setpoint - position",
    "record[a, i, 6] = outputs[a, OUT_SPEED]",
    "record[a, i, 7] = sa[SPEED_CMD]",
)


def lean_record_ratio(rounds: int) -> dict[str, float]:
    """CPU per training replay of the master compiled just in time, as it is and without the
    stores of :data:`UNREAD_STORES` (medians of ``rounds``), the median of the rounds' ratios
    lean / full; raises if the columns read differ."""
    import numba

    from twin_cosim import cosim
    from twin_cosim.loops import kernels

    source = inspect.getsource(kernels.master.py_func).replace("@numba.njit(cache=True)\n", "")
    lean = source.replace("def master(", "def lean_master(")
    for store in UNREAD_STORES:
        lean = lean.replace(store, "pass")
    namespace = dict(vars(kernels))
    exec(source, namespace)  # the same function, compiled here as the lean one is
    exec(lean, namespace)
    loops = {
        "full": SimpleNamespace(master=numba.njit(namespace["master"])),
        "lean": SimpleNamespace(master=numba.njit(namespace["lean_master"])),
    }
    scenario = load_scenario(SCENARIO)
    training = cut(scenario, scenario.reference.time[-1] / 2)
    compiled = cosim.compiled_loops
    times: dict[str, list[float]] = {"full": [], "lean": []}
    records = {}
    try:
        with Plant(scenario.plant_fmu()) as plant:
            for k in range(rounds + 1):  # the first round compiles
                order = ("full", "lean") if k % 2 else ("lean", "full")
                for name in order:
                    cosim.compiled_loops = lambda name=name: loops[name]
                    start = time.process_time()
                    records[name] = run_scenario(plant, training)
                    if k:
                        times[name].append(time.process_time() - start)
    finally:
        cosim.compiled_loops = compiled
    for column in ("t", "x", "motor_angle", "current"):
        if not (records["full"][column] == records["lean"][column]).all():
            raise AssertionError(f"the lean loop changes {column}")
    return {
        "full_cpu_s": statistics.median(times["full"]),
        "lean_cpu_s": statistics.median(times["lean"]),
        "ratio_of_medians": statistics.median(times["lean"]) / statistics.median(times["full"]),
        "median_of_ratios": statistics.median(
            [b / a for a, b in zip(times["full"], times["lean"], strict=True)]
        ),
    }


def synthesized(name: str, folder: Path) -> Path:
    """The machine's run as a measured CSV (synthesized, written, to be read back)."""
    scenario = load_scenario(SCENARIO)
    effects = [parse_effect(e) for e in MACHINES[name]]
    synthesis = synthesize(scenario, effects, perturb=0.02, seed=1)
    path = folder / f"{name}.csv"
    synthesis.run.frame().to_csv(path, index=False)
    return path


def diagnosed(path: Path, workers: int, cache: bool) -> tuple[dict[str, Any], float]:
    """The diagnosis' summary and its wall time (s), the pool's start included."""
    scenario = load_scenario(SCENARIO)
    start = time.perf_counter()
    result = diagnose(
        scenario,
        [read_measured_csv(path)],
        settings=settings_from(scenario),
        workers=workers,
        replay_cache=cache,
    )
    return summary(result), time.perf_counter() - start


def decisions(result: dict[str, Any]) -> dict[str, Any]:
    """What must not change with the caches: the accepted effects and their values, every
    step's, round's, swap's and refit's record, the final plant, what is left."""
    keys = ("accepted", "marginal", "dropped", "swaps", "refits", "steps", "effects", "rounds")
    kept = {key: result[key] for key in keys}
    kept["final_plant_parameters"] = result["final_plant_parameters"]
    kept["remaining"] = result["gap"]["remaining"]
    kept["replays"] = {
        stage: row["replays"] for stage, row in result["time"].items() if stage not in NOT_STAGES
    }
    return kept


def replays_by_kind(time_: dict[str, Any]) -> tuple[int, int]:
    """Replays run of the training half (the fits', the uncertainty's) and of the whole run
    (the replay tasks of the judging runs)."""
    training = judging = 0
    for stage, row in time_.items():
        if stage in NOT_STAGES:
            continue
        fitted = sum(f["replays_run"] for f in row.get("fits") or [])
        if stage == "uncertainty":
            fitted = row["replays_run"]
        training += fitted
        judging += row["replays_run"] - fitted
    return training, judging


def stage_table(result: dict[str, Any], wall_s: float, cost: dict[str, float], workers: int):
    """Lines of the per-stage table of one diagnosis."""
    time_ = result["time"]
    total = time_["total"]
    per_replay = total["cpu_s"] / max(total["replays_run"], 1)
    lines = [
        f"  {'stage':24s} {'replays':>7s} {'run':>6s} {'cached':>6s} {'CPU s':>7s} "
        f"{'wall s':>7s} {'share':>6s} {'CPU/replay s':>12s}"
    ]
    for stage, row in time_.items():
        if stage in NOT_STAGES:
            continue
        lines.append(
            f"  {stage:24s} {row['replays']:7d} {row['replays_run']:6d} {row['cache_hits']:6d} "
            f"{row['cpu_s']:7.1f} {row['wall_s']:7.1f} {row['wall_s'] / total['wall_s']:6.1%} "
            f"{row['cpu_s'] / max(row['replays_run'], 1):12.4f}"
        )
    lines.append(
        f"  {'total':24s} {total['replays']:7d} {total['replays_run']:6d} "
        f"{total['cache_hits']:6d} {total['cpu_s']:7.1f} {total['wall_s']:7.1f} {1:6.1%} "
        f"{per_replay:12.4f}"
    )
    parent = time_["diagnosis"]["parent_cpu_s"]
    training, judging = replays_by_kind(time_)
    limit = (
        training * cost["training_replay_cpu_s"] + judging * cost["judging_replay_cpu_s"]
    ) / workers
    lines.append(
        f"  wall of the diagnosis {wall_s:.1f} s (selection {total['wall_s']:.1f} s); parent CPU "
        f"{parent:.1f} s; idle-core estimate {time_['diagnosis']['idle_wall_estimate_s']:.1f} s; "
        f"limit: {training} training and {judging} whole-run replays run at the costs above / "
        f"{workers} cores = {limit:.1f} s"
    )
    for stage, row in time_.items():
        fits = row.get("fits") or []
        if stage in NOT_STAGES or not fits:
            continue
        lines.append(
            f"  fits of {stage}: {len(fits)}, replays {sum(f['replays'] for f in fits)} "
            f"(searches {sum(f['search_replays'] for f in fits)}), "
            f"local iterations {sum(f['iterations'] for f in fits)}, "
            f"run {sum(f['replays_run'] for f in fits)}, "
            f"cached {sum(f['cache_hits'] for f in fits)}, "
            f"CPU {sum(f['cpu_s'] for f in fits):.1f} s, "
            f"longest {max(f['wall_s'] for f in fits):.1f} s wall "
            f"({max(fits, key=lambda f: f['wall_s'])['fit']})"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2, help="replay processes (default 2)")
    parser.add_argument(
        "--machines", nargs="+", choices=list(MACHINES), default=list(MACHINES), metavar="NAME"
    )
    parser.add_argument("--repeats", type=int, default=7, help="replays timed per kind")
    parser.add_argument(
        "--compare", action="store_true", help="diagnose again without the replay caches"
    )
    parser.add_argument(
        "--lean-record",
        type=int,
        default=0,
        metavar="ROUNDS",
        help="also time the compiled loop without the unread record columns, ROUNDS rounds",
    )
    parser.add_argument("--json", type=Path, help="write every figure to this file")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    cost = replay_cost(args.repeats)
    print(
        f"one replay: training half {cost['training_replay_cpu_s']:.4f} s CPU, whole run "
        f"{cost['judging_replay_cpu_s']:.4f} s CPU (median of {args.repeats}), "
        f"{cost['compiled_loop_share']:.1%} of it in the compiled loop; load average {load:.2f}"
    )
    report: dict[str, Any] = {"replay_cost": cost, "load_before": load, "machines": {}}
    if args.lean_record:
        lean = report["lean_record"] = lean_record_ratio(args.lean_record)
        print(
            f"lean record: {lean['lean_cpu_s']:.4f} s against {lean['full_cpu_s']:.4f} s CPU per "
            f"training replay (medians of {args.lean_record}), ratio of the medians "
            f"{lean['ratio_of_medians']:.3f}, median of the rounds' ratios "
            f"{lean['median_of_ratios']:.3f}; t, x, motor_angle and current the same"
        )
    identical = True
    with tempfile.TemporaryDirectory() as folder:
        for name in args.machines:
            path = synthesized(name, Path(folder))
            runs = {"cached": diagnosed(path, args.workers, cache=True)}
            if args.compare:
                runs["uncached"] = diagnosed(path, args.workers, cache=False)
            for label, (result, wall_s) in runs.items():
                print(f"\n{name} machine ({label}): accepted {result['accepted']}")
                print("\n".join(stage_table(result, wall_s, cost, args.workers)))
            entry: dict[str, Any] = {
                label: {"accepted": result["accepted"], "wall_s": wall_s, "time": result["time"]}
                for label, (result, wall_s) in runs.items()
            }
            if args.compare:
                (cached, _), (uncached, _) = runs["cached"], runs["uncached"]
                same = decisions(cached) == decisions(uncached)
                identical = identical and same
                a, b = cached["time"]["total"], uncached["time"]["total"]
                entry["same_decisions_and_values"] = same
                entry["ratios"] = {
                    "replays_run": a["replays_run"] / b["replays_run"],
                    "cpu": a["cpu_s"] / b["cpu_s"],
                    "cpu_per_replay_asked": (a["cpu_s"] / a["replays"])
                    / (b["cpu_s"] / b["replays"]),
                }
                print(
                    f"  with / without the caches: replays run {a['replays_run']} / "
                    f"{b['replays_run']} = {entry['ratios']['replays_run']:.3f}, worker CPU "
                    f"{a['cpu_s']:.1f} / {b['cpu_s']:.1f} s = {entry['ratios']['cpu']:.3f}; "
                    f"decisions and values {'the same' if same else 'DIFFER'}"
                )
            report["machines"][name] = entry
    report["load_after"] = os.getloadavg()[0]
    print(f"\nload average after: {report['load_after']:.2f}")
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))
    return 0 if identical else 1


if __name__ == "__main__":
    raise SystemExit(main())
