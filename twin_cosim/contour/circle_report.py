"""``twin circle``'s outputs: the test in one or both directions, its summary (ISO 230-4's G, F,
H, the reversal spikes, the ballbar's diagnostics, the feed reached) and the polar plot.

The polar plot draws the radial deviation magnified around the nominal circle, as ballbar
software does: the rings are whole divisions of a round scale (1, 2 or 5 um times a power of
ten per division, written on the plot), each direction (or the measured and the twin's path)
in its colour, the reversal spikes marked where they peak; the figures stand in a table beside
it, so that no label lies on a trace.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.contour.ballbar import ballbar_figures, cyclic_periods
from twin_cosim.contour.circle import (
    DIRECTIONS,
    MM_PER_MIN,
    CircleResult,
    CircleSpec,
    hysteresis,
    run_circle,
)
from twin_cosim.contour.interpolation import FEED_SHORTFALL
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.scenario import load_axes_parameters, load_machine

COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple")
RING_SHARE = 0.4  # the deviation band drawn as this share of the plot's radius
RINGS = 6  # divisions of the deviation band, about
MARKED_SHARE = 0.1  # spikes of at least this share of the drawn band (and 0.5 um) are marked


def circular_test(
    scenario: str,
    radius_mm: float,
    feed_mm_min: float,
    direction: str,
    params: str | None,
    out: Path,
    command: str,
    fast: bool = True,
    feed_override: float = 100.0,
) -> tuple[dict[str, Any], Callable[[], None]]:
    """Run the test, write ``contour_<direction>.csv`` (the contour records) into ``out``.

    Parameters
    ----------
    scenario
        Machine scenario (file or shipped name).
    radius_mm, feed_mm_min
        Radius (mm) and programmed feed (mm/min).
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
    feed_override
        Feed override, % of the programmed feed.

    Returns
    -------
    tuple
        The summary: ``G_um``, ``F_um`` (the largest over the directions), ``H_um`` (both
        directions), ``spikes`` (each direction's quadrant transitions: ``direction``,
        ``angle_deg``, ``axis``, ``height_um``, ``width_ms``, ``peak_deg``), ``ballbar`` (the
        ballbar's diagnostics, :func:`~twin_cosim.contour.ballbar.ballbar_figures`),
        ``directions`` (each one's figures), the feed asked, its override and the feed reached
        (mm/min), ``warnings`` (the feed reached below the feed asked), parameters and outputs;
        and what draws ``circle.png`` (called after the summary is saved, or not).
    """
    machine = load_machine(scenario)
    if params:
        machine = machine.with_tuned(load_axes_parameters(params, machine.axis_names))
    directions = DIRECTIONS if direction == "both" else (direction,)
    asked = feed_mm_min * feed_override / 100.0
    spec_of = {name: CircleSpec(radius_mm * 1e-3, asked * MM_PER_MIN, name) for name in directions}
    results: list[CircleResult] = []
    warnings: list[str] = []
    with MachinePlants(machine) as plants:
        for name in directions:
            run = run_circle(machine, plants, spec_of[name], fast)  # refused before it runs
            out.mkdir(parents=True, exist_ok=True)
            run.record.contour.frame().to_csv(out / f"contour_{name}.csv", index=False)
            results.append(run.result)
            feed = run.motion.feeds[0]
            if feed.reached < feed.programmed * (1 - FEED_SHORTFALL):
                warnings.append(
                    f"{name}: feed {feed.reached / MM_PER_MIN:.0f} mm/min reached of "
                    f"{asked:g} mm/min asked: capped by {feed.cap_reason}"
                )
    h = hysteresis(*results) if len(results) == 2 else None
    ballbar = ballbar_figures(results, radius_mm * 1e-3, cyclic_periods(machine))

    def draw() -> None:
        labelled = [(r.direction.upper(), r) for r in results]
        rows = [
            (f"{name} ({r.direction.upper()})", {"value": f"{getattr(r, name + '_um'):.2f} um"})
            for name in ("G", "F")
            for r in results
        ]
        if h is not None:
            rows.append(("H (CW against CCW)", {"value": f"{h:.2f} um"}))
        table = rows + ballbar_table({"value": ballbar})
        plot_circle(labelled, radius_mm, command, out / "circle.png", table)

    summary: dict[str, Any] = {
        "scenario": str(machine.source),
        "radius_mm": radius_mm,
        "feed_mm_min": feed_mm_min,
        "feed_override_pct": feed_override,
        "feed_reached_mm_min": min(r.speed_mm_min for r in results),
        "G_um": max(r.G_um for r in results),
        "F_um": max(r.F_um for r in results),
    }
    if h is not None:
        summary["H_um"] = h
    summary["spikes"] = [
        {"direction": r.direction, **s} for r in results for s in r.summary()["spikes"]
    ]
    summary["ballbar"] = ballbar
    summary["directions"] = {r.direction: r.summary() for r in results}
    summary["params"] = {a.name: a.tuned.as_dict() for a in machine.axes}
    summary["geometry"] = machine.geometry.as_dict()
    summary["warnings"] = warnings
    summary["outputs"] = {"plot": str(out / "circle.png"), "folder": str(out)}
    return summary, draw


def signed(value: float, digits: int = 2) -> str:
    """``+1.23``: a signed figure, 0 without a sign (not ``-0.00``)."""
    rounded = round(value, digits)
    return f"{rounded:+.{digits}f}" if rounded else f"{0:.{digits}f}"


def _number(value: float | None, unit: str, digits: int = 2) -> str:
    """A figure for a reader: ``+1.23 um``, or a dash when there is none."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{signed(value, digits)} {unit}"


def ballbar_table(figures: dict[str, dict[str, Any]]) -> list[tuple[str, dict[str, str]]]:
    """The ballbar's diagnostics as table rows: (figure, {column: text}) for each column's
    figures (one column per path: the test's, or the measured and the twin's)."""

    def row(name: str, pick: Callable[[dict[str, Any]], float | None], unit: str, digits=2):
        return (name, {col: _number(pick(f), unit, digits) for col, f in figures.items()})

    rows = [
        row("squareness", lambda f: f["squareness_um_per_m"], "um/m", 1),
        row("scale mismatch X-Y", lambda f: f["scale_mismatch_um_per_m"], "um/m", 1),
        row("servo mismatch (Y lags)", lambda f: f["servo_mismatch_ms"], "ms", 3),
    ]
    for axis in ("X", "Y"):
        for end, sign in (("positive", "+"), ("negative", "-")):
            rows.append(row(f"backlash {axis}{sign}", _at("backlash_um", axis, end), "um"))
    for axis in ("X", "Y"):
        for end, sign in (("positive", "+"), ("negative", "-")):
            rows.append(
                row(f"reversal spike {axis}{sign}", _at("reversal_spikes_um", axis, end), "um")
            )
    for axis in ("X", "Y"):
        rows.append(row(f"lateral play {axis}", _at("lateral_play_um", axis), "um"))
    for axis in ("X", "Y"):
        rows.append(row(f"straightness {axis}", _at("straightness_um", axis), "um"))
    for axis in ("X", "Y"):
        rows.append(row(f"cyclic error {axis}", _at("cyclic_error_um", axis), "um"))
    for axis in ("X", "Y"):
        rows.append(row(f"centre offset {axis}", _at("centre_offset_um", axis), "um"))
    return rows


def _at(key: str, *path: str) -> Callable[[dict[str, Any]], float | None]:
    """Pick ``figures[key][path...]`` (None where the figure is null)."""

    def pick(figures: dict[str, Any]) -> float | None:
        value = figures[key]
        for step in path:
            if value is None:
                return None
            value = value[step]
        return value

    return pick


def ring_division(span_um: float) -> float:
    """A round division (um: 1, 2 or 5 times a power of ten) that cuts ``span_um`` into about
    :data:`RINGS` rings."""
    raw = max(span_um, 1e-3) / RINGS
    power = 10.0 ** math.floor(math.log10(raw))
    return next(step * power for step in (1.0, 2.0, 5.0, 10.0) if step * power >= raw)


def paths_table(
    results: dict[str, CircleResult], ballbar: dict[str, dict[str, Any]]
) -> list[tuple[str, dict[str, str]]]:
    """The table of paths side by side (a measured test and the twin's replay): their G, F and
    ballbar's diagnostics, one column each."""
    rows = [
        (name, {col: f"{getattr(r, name + '_um'):.2f} um" for col, r in results.items()})
        for name in ("G", "F")
    ]
    return rows + ballbar_table(ballbar)


def plot_circle(
    results: Sequence[tuple[str, CircleResult]],
    radius_mm: float,
    command: str,
    path: Path,
    table: list[tuple[str, dict[str, str]]],
) -> Path:
    """Write the polar plot of one circle's paths beside the table of its figures; returns
    ``path``.

    Parameters
    ----------
    results
        (label, evaluation) of each path drawn: CW and CCW, or a measured test and the twin.
    radius_mm
        Nominal radius, mm.
    command
        The command that made the figure (written under the title).
    path
        PNG file to write.
    table
        Rows (figure, {column: text}): ISO 230-4's figures, then the ballbar's
        (:func:`ballbar_table`).
    """
    import matplotlib  # only to draw

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    deviations = np.concatenate([r.deviation_um for _, r in results])
    division = ring_division(float(deviations.max() - deviations.min()))
    low = division * (math.floor(min(float(deviations.min()), 0.0) / division) - 1)
    high = division * (math.ceil(max(float(deviations.max()), 0.0) / division) + 1)
    fig = plt.figure(figsize=(13, 8.2))
    ax = fig.add_axes((0.03, 0.12, 0.56, 0.74), projection="polar")
    ax.set_rorigin(low - (high - low) * (1 - RING_SHARE) / RING_SHARE)
    ax.set_rlim(low, high)
    ax.set_rticks(np.arange(low, high + division / 2, division))
    ax.set_yticklabels([])
    ax.set_thetagrids(range(0, 360, 45), [f"{a}°" for a in range(0, 360, 45)], fontsize=9)
    circle = np.linspace(0.0, 2 * math.pi, 721)
    ax.plot(circle, np.zeros_like(circle), color="0.3", ls="--", lw=0.8, label="nominal circle")
    for (label, result), colour in zip(results, COLOURS, strict=False):
        order = np.argsort(result.angle_deg)
        ax.plot(
            np.radians(result.angle_deg[order]),
            result.deviation_um[order],
            color=colour,
            lw=1.2,
            label=f"{label} at {result.speed_mm_min:.0f} mm/min",
        )
        shown = max(0.5, MARKED_SHARE * (high - low))
        for spike in (s for s in result.spikes if abs(s.height_um) >= shown):
            at = np.interp(spike.peak_deg, result.angle_deg[order], result.deviation_um[order])
            ax.plot(math.radians(spike.peak_deg), at, marker="v", color=colour, ms=6, ls="")
    ax.text(
        0.0,
        0.0,
        f"scale {division:g} um/div\nnominal circle at {0:g} um (dashed)",
        transform=ax.transAxes,
        fontsize=8,
        va="bottom",
    )
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.04), fontsize=8, ncol=3)
    ax.set_title(
        f"circular test, radius {radius_mm:g} mm: radial deviation from the nominal circle",
        fontsize=10,
        pad=18,
    )
    columns = list(table[0][1])
    side = fig.add_axes((0.62, 0.08, 0.36, 0.8))
    side.axis("off")
    cells = [[name, *(values.get(c, "") for c in columns)] for name, values in table]
    header = ["figure", *columns]
    drawn = side.table(cellText=cells, colLabels=header, loc="upper left", cellLoc="left")
    drawn.auto_set_font_size(False)
    drawn.set_fontsize(8)
    drawn.scale(1.0, 1.15)
    for (row, _), cell in drawn.get_celld().items():
        cell.set_edgecolor("0.85")
        if row == 0:
            cell.set_text_props(weight="bold")
    fig.text(0.5, 0.965, command, ha="center", fontsize=9, family="monospace")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
