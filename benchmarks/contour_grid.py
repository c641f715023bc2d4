"""Fine-Tune against a tuned set on the 3 x 3 grid of circles (docs/contouring.md).

Runs ``scenarios/xy_table.yaml`` on circles of radius 5, 10, 25 mm at 500, 1000, 2000 mm/min in
both directions, once with the scenario's sets (Fine-Tune on both axes) and once with the tuned
sets of ``--params`` (a ``twin optimize`` result.json), and prints per cell the largest reversal
spike and G of each, and the reductions against the goal (spike -80 %, G -50 % in every cell).

    python benchmarks/contour_grid.py --params out/optimize-machine-cmaes-seed0/result.json
"""

from __future__ import annotations

import argparse

from twin_cosim.contour.circle import DIRECTIONS, MM_PER_MIN, CircleSpec, run_circle
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.scenario import load_axes_parameters, load_machine

RADII_MM = (5.0, 10.0, 25.0)
FEEDS_MM_MIN = (500.0, 1000.0, 2000.0)


def worst(machine, plants, radius_mm: float, feed: float) -> tuple[float, float]:
    """Largest |spike| and G (um) over both directions of one circle."""
    spike = g = 0.0
    for direction in DIRECTIONS:
        spec = CircleSpec(radius_mm * 1e-3, feed * MM_PER_MIN, direction)
        result = run_circle(machine, plants, spec).result
        spike = max(spike, max(abs(s.height_um) for s in result.spikes))
        g = max(g, result.G_um)
    return spike, g


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--params", required=True, help="tuned sets (twin optimize result.json)")
    parser.add_argument("--scenario", default="xy_table")
    args = parser.parse_args()
    reference = load_machine(args.scenario)
    tuned = reference.with_tuned(load_axes_parameters(args.params, reference.axis_names))
    print(
        "| radius [mm] | feed [mm/min] | spike FT [um] | spike tuned [um] | spike change |"
        " G FT [um] | G tuned [um] | G change |"
    )
    print("|---|---|---|---|---|---|---|---|")
    met = 0
    with MachinePlants(reference) as plants:
        for radius in RADII_MM:
            for feed in FEEDS_MM_MIN:
                spike_ft, g_ft = worst(reference, plants, radius, feed)
                spike, g = worst(tuned, plants, radius, feed)
                d_spike, d_g = spike / spike_ft - 1, g / g_ft - 1
                met += d_spike <= -0.8 and d_g <= -0.5
                print(
                    f"| {radius:g} | {feed:g} | {spike_ft:.2f} | {spike:.2f} | {d_spike:+.0%} |"
                    f" {g_ft:.2f} | {g:.2f} | {d_g:+.0%} |",
                    flush=True,
                )
    print(f"\ncells meeting the goal (spike -80 % and G -50 %): {met} of 9")


if __name__ == "__main__":
    main()
