"""Wall time of one reference-1 run: fast path, fmpy path and a C loop (the limit), as ratios.

All three step the same FMU through the same set/step/get sequence; the C loop replays the
currents of the fast run with no controller. Each figure is the best of several repeats measured
in this one run (the machine is shared and noisy); only the ratios are meaningful.

    python benchmarks/step_speed.py [--repeats N]
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

from fmu_build.build import fmi_headers_dir
from twin_cosim.cosim import INPUT_NAMES, OUTPUT_NAMES, run_scenario
from twin_cosim.plant import Plant
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def best_of(repeats: int, function) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scenario = load_scenario(ROOT / "scenarios" / "reference1.yaml")
    steps = (len(scenario.reference.position)) * scenario.settings.speed_steps_per_position_step
    with Plant() as plant, tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        record = run_scenario(plant, scenario)  # compiles or loads the compiled loop
        fast = best_of(args.repeats, lambda: run_scenario(plant, scenario))
        slow = best_of(1, lambda: run_scenario(plant, scenario, fast=False))
        currents = np.repeat(
            record["current"].to_numpy(), scenario.settings.speed_steps_per_position_step
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
            *(str(plant.value_reference(n)) for n in INPUT_NAMES + OUTPUT_NAMES),
        ]
        c_loop = min(
            float(subprocess.run(command, capture_output=True, text=True, check=True).stdout)
            for _ in range(args.repeats)
        )
    print(f"reference 1: {scenario.reference.duration:.2f} s simulated, {steps} speed-loop steps")
    print(f"{'path':<22}{'wall [s]':>10}{'us/step':>10}{'x C loop':>10}")
    for name, wall in (
        ("C loop (limit)", c_loop),
        ("fast path (numba)", fast),
        ("fmpy path (Python)", slow),
    ):
        print(f"{name:<22}{wall:>10.4f}{wall / steps * 1e6:>10.3f}{wall / c_loop:>10.2f}")


if __name__ == "__main__":
    main()
