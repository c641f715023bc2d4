"""The circular test as ``twin circle`` runs it: one or both directions, figures and files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from twin_cosim.contour.circle_test import DIRECTIONS, MM_PER_MIN, CircleSpec, run_circle
from twin_cosim.contour.iso230 import hysteresis
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.contour.polar_plot import plot_circle
from twin_cosim.scenario import load_axes_parameters, load_machine


def circular_test(
    scenario: str,
    radius_mm: float,
    feed_mm_min: float,
    direction: str,
    params: str | None,
    out: Path,
    command: str,
    fast: bool = True,
) -> dict[str, Any]:
    """Run the test, write ``contour_<direction>.csv`` and ``circle.png`` into ``out``.

    Parameters
    ----------
    scenario
        Machine scenario (file or shipped name).
    radius_mm, feed_mm_min
        Radius (mm) and feed (mm/min).
    direction
        ``cw``, ``ccw`` or ``both``.
    params
        ``--params``: a Table 3 set or a file (one set, or one per axis); None: the scenario's.
    out
        Output folder.
    command
        The command line, written in the figure.
    fast
        Compiled path (default) or the fmpy reference path.

    Returns
    -------
    dict
        ``G_um``, ``F_um`` (the largest over the directions), ``H_um`` (both directions),
        ``spikes`` (each direction's quadrant transitions: ``direction``, ``angle_deg``,
        ``axis``, ``height_um``, ``width_ms``, ``peak_deg``), ``directions`` (each one's
        figures and servo-mismatch signature), radius, feed, parameters and outputs.
    """
    machine = load_machine(scenario)
    if params:
        machine = machine.with_tuned(load_axes_parameters(params, machine.axis_names))
    directions = DIRECTIONS if direction == "both" else (direction,)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    with MachinePlants(machine) as plants:
        for name in directions:
            spec = CircleSpec(radius_mm * 1e-3, feed_mm_min * MM_PER_MIN, name)
            run = run_circle(machine, plants, spec, fast)
            run.record.contour.to_csv(out / f"contour_{name}.csv", index=False)
            results.append(run.result)
    h = hysteresis(*results) if len(results) == 2 else None
    labelled = [(r.direction.upper(), r) for r in results]
    plot_circle(labelled, radius_mm, h, command, out / "circle.png")
    summary: dict[str, Any] = {
        "scenario": str(machine.source),
        "radius_mm": radius_mm,
        "feed_mm_min": feed_mm_min,
        "G_um": max(r.G_um for r in results),
        "F_um": max(r.F_um for r in results),
    }
    if h is not None:
        summary["H_um"] = h
    summary["spikes"] = [
        {"direction": r.direction, **s} for r in results for s in r.summary()["spikes"]
    ]
    summary["directions"] = {r.direction: r.summary() for r in results}
    summary["params"] = {a.name: a.tuned.as_dict() for a in machine.axes}
    summary["outputs"] = {"plot": str(out / "circle.png"), "folder": str(out)}
    return summary


def measured_circular_test(
    scenario: str, measured: str, out: Path, command: str, fast: bool = True
) -> dict[str, Any]:
    """Replay and diagnose a measured circular test; write ``circle.png`` (machine and twin).

    Returns the diagnosis of :func:`twin_cosim.contour.circle_diagnosis.diagnose_circle`.
    """
    from twin_cosim.contour.circle_diagnosis import diagnose_circle
    from twin_cosim.contour.measured_circle import read_measured_circle

    machine = load_machine(scenario)
    test = read_measured_circle(measured)
    out.mkdir(parents=True, exist_ok=True)
    found = diagnose_circle(machine, test, fast, workers=1)
    paths = found.pop("paths")
    plot_circle(
        [("machine", paths["machine"]), ("twin", paths["twin"])],
        test.radius * 1e3,
        None,
        command,
        out / "circle.png",
    )
    found["outputs"] = {"plot": str(out / "circle.png"), "folder": str(out)}
    return found
