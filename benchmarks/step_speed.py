"""Wall time of one reference-1 run: fast path, fmpy path and a C loop (the limit), as ratios.

All three step the same FMU through the same set/step/get sequence; the C loop replays the
currents of the fast run with no controller. Each figure is the best of several repeats measured
in this one run (the machine is shared and noisy); only the ratios are meaningful. The fast path
is also timed in this thread's CPU time (the stepping runs in it), which the other processes of
a loaded machine disturb less than the wall.

    python benchmarks/step_speed.py [--repeats N] [--paths fast,fmpy,c] [--json]

With ``--json`` the figures (seconds per speed-loop step of each path, wall and, for the fast
path, CPU) are printed as one JSON object instead of the table: what ``benchmarks/paired.py``
reads.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from fmu_build.build import fmi_headers_dir
from twin_cosim.cosim import run_scenario
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS, Plant
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def best_of(repeats: int, function) -> float:
    """The least wall (s) of ``repeats`` calls."""
    return min(timed(function)[0] for _ in range(repeats))


def timed(function) -> tuple[float, float]:
    """Wall and this thread's CPU time (s) of one call."""
    wall, cpu = time.perf_counter(), time.thread_time()
    function()
    return time.perf_counter() - wall, time.thread_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--paths", default="fast,fmpy,c", help="the paths timed, of fast, fmpy and c (the C loop)"
    )
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    paths = set(args.paths.split(","))
    scenario = load_scenario(ROOT / "scenarios" / "reference1.yaml")
    steps = (len(scenario.reference.position)) * scenario.settings.speed_steps_per_position_step
    with Plant() as plant, tempfile.TemporaryDirectory() as tmp:
        record = run_scenario(plant, scenario)  # compiles or loads the compiled loop
        walls, cpu = {}, {}
        if "fast" in paths:
            fast = [timed(lambda: run_scenario(plant, scenario)) for _ in range(args.repeats)]
            walls["fast path (numba)"] = min(wall for wall, _ in fast)
            cpu["fast path (numba), CPU"] = min(spent for _, spent in fast)
        if "fmpy" in paths:
            walls["fmpy path (Python)"] = best_of(
                1, lambda: run_scenario(plant, scenario, fast=False)
            )
        if "c" in paths:
            walls["C loop (limit)"] = c_loop_wall(plant, scenario, record, Path(tmp), args.repeats)
    if args.json:
        figures = {**walls, **cpu}
        print(json.dumps({f"{name} [s/step]": value / steps for name, value in figures.items()}))
        return
    print(f"reference 1: {scenario.reference.duration:.2f} s simulated, {steps} speed-loop steps")
    c_loop = walls.get("C loop (limit)")
    print(f"{'path':<22}{'wall [s]':>10}{'us/step':>10}{'x C loop':>10}")
    for name, wall in walls.items():
        versus = f"{wall / c_loop:>10.2f}" if c_loop else ""
        print(f"{name:<22}{wall:>10.4f}{wall / steps * 1e6:>10.3f}{versus}")
    for name, spent in cpu.items():
        print(f"{name:<22}{spent:>10.4f}{spent / steps * 1e6:>10.3f}  (CPU time)")


def c_loop_wall(plant: Plant, scenario, record, tmp: Path, repeats: int) -> float:
    """Best wall (s) of the C loop replaying the currents of ``record`` on the plant's FMU."""
    currents = np.repeat(
        np.asarray(record["current"]), scenario.settings.speed_steps_per_position_step
    )
    currents.astype(np.float64).tofile(tmp / "currents.f64")
    with zipfile.ZipFile(plant.fmu_path) as archive:
        archive.extract("binaries/linux64/drive2mass.so", tmp)
    subprocess.run(
        [
            "gcc",
            "-O2",
            "-std=c99",
            f"-I{fmi_headers_dir()}",
            "-o",
            str(tmp / "c_loop"),
            str(ROOT / "benchmarks" / "c_loop.c"),
            "-ldl",
        ],
        check=True,
    )
    command = [
        str(tmp / "c_loop"),
        str(tmp / "binaries/linux64/drive2mass.so"),
        plant.description.guid,
        str(tmp / "currents.f64"),
        repr(scenario.settings.speed_period),
        *(str(plant.value_reference(n)) for n in CONTRACT_INPUTS + CONTRACT_OUTPUTS),
    ]
    return min(
        float(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
        for _ in range(repeats)
    )


if __name__ == "__main__":
    main()
