"""Wall time of a two-axis run against a one-axis run of the same length (compiled master).

The X-Y table of ``scenarios/xy_table.yaml`` runs a circle (radius 10 mm, 1000 mm/min, CCW;
its feed-in, 360 degrees and feed-out): once with both axes together, once with the X axis
alone with the same reference, both on the compiled master (:func:`twin_cosim.cosim.run_axes`).
Each figure is the best of several repeats measured in this one run, alternating the two (the
machine is shared and noisy), in wall and in this thread's CPU time (the stepping runs in it;
other processes of a loaded machine disturb it less); the ratio is the figure to compare (goal:
at most 2.2).

    python benchmarks/contour_speed.py [--repeats N] [--json]

With ``--json`` the figures (seconds per speed-loop step of each run, wall and CPU, and the ratio
of the walls) are printed as one JSON object: what ``benchmarks/paired.py`` reads.
"""

from __future__ import annotations

import argparse
import json
import time

from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, circle_motion
from twin_cosim.contour.machine_run import MachinePlants, axis_grids
from twin_cosim.cosim import AxisRun, run_axes
from twin_cosim.plant import Plant
from twin_cosim.scenario import load_machine


def timed(function) -> tuple[float, float]:
    """Wall and this thread's CPU time (s) of one call."""
    wall, cpu = time.perf_counter(), time.thread_time()
    function()
    return time.perf_counter() - wall, time.thread_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    machine = load_machine("xy_table")
    motion, _ = circle_motion(machine, CircleSpec(0.01, 1000 * MM_PER_MIN, "ccw"))
    grids = axis_grids(machine, motion)
    x, y = machine.axes
    with MachinePlants(machine) as plants, Plant(x.plant_fmu(), instance_name="alone") as alone:
        axes = [
            AxisRun(a.name, plants.plants[a.name], grids[a.name], a.tuned, a.settings)
            for a in machine.axes
        ]

        alone_x = [AxisRun("X", alone, grids["X"], x.tuned, x.settings)]

        def two() -> None:
            run_axes(axes)

        def one() -> None:
            run_axes(alone_x)

        two(), one()  # compile or load the compiled loops
        runs_two, runs_one = [], []
        for _ in range(args.repeats):
            runs_two.append(timed(two))
            runs_one.append(timed(one))
    best_two, best_one = (min(wall for wall, _ in runs) for runs in (runs_two, runs_one))
    cpu_two, cpu_one = (min(cpu for _, cpu in runs) for runs in (runs_two, runs_one))
    steps = len(grids["X"].position) * x.settings.speed_steps_per_position_step
    if args.json:
        figures = {
            "one axis [s/step]": best_one / steps,
            "two axes [s/step]": best_two / steps,
            "one axis, CPU [s/step]": cpu_one / steps,
            "two axes, CPU [s/step]": cpu_two / steps,
            "two / one": best_two / best_one,
        }
        print(json.dumps(figures))
        return
    print(f"{steps} speed-loop steps per axis ({grids['X'].duration:.2f} s of motion)")
    print(f"one axis:  {best_one * 1e3:8.1f} ms  {best_one / steps * 1e6:.3f} us per step")
    print(f"two axes:  {best_two * 1e3:8.1f} ms  {best_two / steps * 1e6:.3f} us per step")
    print(f"ratio two / one: {best_two / best_one:.2f} (goal: at most 2.2)")


if __name__ == "__main__":
    main()
