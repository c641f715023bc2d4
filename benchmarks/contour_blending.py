"""Corner blending against exact stop on a CAM-style program of many short chords of an arc.

The X-Y table of ``scenarios/xy_table.yaml`` runs a program of ``--blocks`` G01 chords (default
2000) of a quarter circle of ``--radius`` mm (default 50) at ``--feed`` mm/min (default 2000),
once with ``G64 P<--tolerance>`` (mm, default 0.005) and once with ``G61`` (exact stop): the
path time of each, their largest contour error, and the wall and this thread's CPU time of the
planner (:func:`twin_cosim.contour.machine_run.plan_on`) and of the run of both axes on the
compiled master (:func:`twin_cosim.contour.machine_run.run_machine`), best of ``--repeats``, in
this one run. The real-time factor is the path time over the planner's and the run's time
together (goal: at least 20 with G64; the numba master runs on one core).

    python benchmarks/contour_blending.py [--blocks N] [--radius MM] [--feed MM_PER_MIN]
        [--tolerance MM] [--repeats N] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from twin_cosim.contour.gcode import parse_program
from twin_cosim.contour.machine_run import MachinePlants, contour_metrics, plan_on, run_machine
from twin_cosim.scenario import load_machine


def timed(function):
    """The result of one call, its wall and this thread's CPU time (s)."""
    wall, cpu = time.perf_counter(), time.thread_time()
    result = function()
    return result, time.perf_counter() - wall, time.thread_time() - cpu


def chord_program(mode: str, blocks: int, radius: float, feed: float) -> str:
    """A CAM post-processor's program: chords of a quarter circle (mm, mm/min)."""
    angles = np.linspace(0.0, math.pi / 2, blocks + 1)[1:]
    chords = [f"X{radius * math.cos(a):.4f} Y{radius * math.sin(a):.4f}" for a in angles]
    head = ["%", "O1001", "G21 G90 G17 G40 G49 G80", mode, "T1 M06", "S12000 M03", "G54"]
    return "\n".join([*head, f"G00 X{radius:.4f} Y0", f"G01 F{feed:g}", *chords, "M05", "M30", "%"])


def measure(machine, plants, text: str, repeats: int) -> dict[str, float]:
    """Plan and run one program ``repeats`` times: its figures, the best times."""
    program = parse_program(text, "chords.nc", machine.axis_names)
    plans, runs = [], []
    for _ in range(repeats):
        motion, wall, cpu = timed(lambda: plan_on(machine, program))
        plans.append((wall, cpu))
        record, wall, cpu = timed(lambda m=motion: run_machine(machine, m, plants))
        runs.append((wall, cpu))
    plan_wall, plan_cpu = (min(p[i] for p in plans) for i in (0, 1))
    run_wall, run_cpu = (min(r[i] for r in runs) for i in (0, 1))
    path_time = motion.end_time - machine.settle
    return {
        "path_time_s": path_time,
        "contour_error_max_um": contour_metrics(record)["contour_error_max_um"],
        "plan_wall_s": plan_wall,
        "plan_cpu_s": plan_cpu,
        "run_wall_s": run_wall,
        "run_cpu_s": run_cpu,
        "real_time_factor": path_time / (plan_wall + run_wall),
        "real_time_factor_cpu": path_time / (plan_cpu + run_cpu),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--blocks", type=int, default=2000)
    parser.add_argument("--radius", type=float, default=50.0, help="mm")
    parser.add_argument("--feed", type=float, default=2000.0, help="mm/min")
    parser.add_argument("--tolerance", type=float, default=0.005, help="G64's P, mm")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    machine = load_machine("xy_table")
    figures = {}
    with MachinePlants(machine) as plants:
        warm_up = chord_program("G61", 4, args.radius, args.feed)
        measure(machine, plants, warm_up, 1)  # compile or load the compiled loops
        for mode in (f"G64 P{args.tolerance:g}", "G61"):
            text = chord_program(mode, args.blocks, args.radius, args.feed)
            figures[mode.split()[0]] = measure(machine, plants, text, args.repeats)
    blended, stopping = figures["G64"], figures["G61"]
    figures["G61 / G64 path time"] = stopping["path_time_s"] / blended["path_time_s"]
    if args.json:
        print(json.dumps(figures))
        return
    print(
        f"{args.blocks} chords of a quarter circle R {args.radius:g} mm at F{args.feed:g} "
        f"(chord {args.radius * math.pi / 2 / args.blocks * 1e3:.1f} um)"
    )
    for mode, found in (("G64 P" + f"{args.tolerance:g}", blended), ("G61", stopping)):
        print(
            f"{mode:>10}: path {found['path_time_s']:7.2f} s, contour error max "
            f"{found['contour_error_max_um']:6.2f} um; planner {found['plan_wall_s']:6.3f} s, "
            f"run {found['run_wall_s']:6.3f} s wall ({found['plan_cpu_s']:.3f} + "
            f"{found['run_cpu_s']:.3f} s CPU): {found['real_time_factor']:.1f} x real time "
            f"({found['real_time_factor_cpu']:.1f} x on CPU time)"
        )
    print(f"G61 / G64 path time: {figures['G61 / G64 path time']:.1f} (goal: at least 3)")


if __name__ == "__main__":
    main()
