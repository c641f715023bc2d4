"""Figures of optimizer campaigns: convergence and the best run against the reference set.

A campaign's two figures are drawn by the command's painter (:mod:`twin_cosim.painter`,
forked at the command's start: matplotlib is loaded and the own set's run made while the
campaign runs), side by side (the best run's record made where it is drawn); the command's
process loads neither matplotlib nor the plant.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.controller_set import set_name
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.algorithms import method_label
from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.store import logged_fitness
from twin_cosim.scenario import Scenario

if TYPE_CHECKING:
    from twin_cosim.optimize.objective import Objective
    from twin_cosim.painter import Painter
    from twin_cosim.run_record import RunRecord

# Statuses of the evaluations shown apart from the valid runs: (marker, what it means)
SET_APART = {
    "violation": ("x", "IAU cap exceeded (penalty + E_pk)"),
    "failed": ("v", "failed (2 x penalty)"),
    "unstable": ("v", "unstable or oscillating (2 x penalty)"),
    "stopped": ("|", "stopped early: worse than the cutoff"),
}


def plot_convergence(campaigns: Mapping[str, Path], path: Path) -> Path:
    """Best E_pk so far of the valid runs against evaluations, one line per campaign; the
    penalised and early-stopped evaluations apart, below (their scores of 1e6 and more would
    stretch the axis of the valid ones)."""
    from matplotlib.figure import Figure  # where figures are drawn only
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda value, _: f"{value:g}")  # 20, not 2 x 10^1

    fig = Figure(figsize=(9, 7))
    ax, apart = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [4, 1.3]})
    labels = []
    any_valid = False
    for row, (label, folder) in enumerate(campaigns.items()):
        fitness, status = logged_fitness(folder)
        evaluation = np.arange(1, len(fitness) + 1)
        valid = np.array([s == "ok" for s in status], dtype=bool)
        labels.append(f"{label} ({len(status) - valid.sum()} of {len(status)})")
        any_valid = any_valid or bool(valid.any())
        (line,) = ax.step(
            evaluation[valid],
            np.minimum.accumulate(fitness[valid]) if valid.any() else [],
            where="post",
            label=f"{label}: best so far",
        )
        ax.plot(evaluation[valid], fitness[valid], ".", ms=3, alpha=0.4, color=line.get_color())
        for kind, (marker, _) in SET_APART.items():
            chosen = np.array([s == kind for s in status], dtype=bool)
            apart.plot(
                evaluation[chosen], np.full(chosen.sum(), row), marker, color=line.get_color()
            )
    ax.set_xscale("log")
    if any_valid:
        ax.set_yscale("log")
    else:  # nothing to scale: say so where the runs would be
        ax.text(0.5, 0.5, "no valid run yet", transform=ax.transAxes, ha="center", va="center")
    for axis in (ax.yaxis, ax.xaxis):
        axis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(plain)
    ax.set_ylabel("E_pk of the valid runs [um]\n(dots: each run; line: best so far)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    apart.set_yticks(range(len(labels)), labels, fontsize=8)
    apart.set_ylim(-0.6, len(labels) - 0.4)
    apart.set_xlabel("evaluations")
    apart.set_title("set apart (penalised or stopped early)", fontsize=9)
    apart.legend(
        handles=[
            Line2D([], [], color="0.3", marker=marker, ls="", label=what)
            for marker, what in SET_APART.values()
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.45),
        ncol=2,
        fontsize=8,
    )
    apart.grid(alpha=0.3, axis="x", which="both")
    # fixed margins that hold the labels and the legend below: tight_layout would draw twice
    fig.subplots_adjust(left=0.2, right=0.97, top=0.97, bottom=0.19, hspace=0.12)
    fig.savefig(path, dpi=110)
    return path


@dataclass(frozen=True)
class OwnSetRun:
    """What both figures of a campaign start from, made by the painter while the campaign
    runs (:func:`start_campaign_plots`): the campaign's first scenario (resolved), its objective
    on a plant of the painter's (whose runs are the figures' records), and the run of the
    scenario's own set."""

    scenario: Scenario
    objective: Objective
    record: RunRecord


def start_campaign_plots(spec: CampaignSpec, painter: Painter) -> None:
    """Have ``painter`` run the campaign's own set now (:func:`run_own_set`), while the
    campaign runs; :func:`write_campaign_plots` then draws with it."""
    painter.prepare(f"{__name__}:run_own_set", spec)


def run_own_set(spec: CampaignSpec) -> OwnSetRun:
    """The campaign's problem, resolved as the campaign resolves it
    (:meth:`~twin_cosim.optimize.axis_problem.AxisProblem.resolve`), its first case run with its
    scenario's own set."""
    problem = AxisProblem.resolve(spec)
    objective = problem.objective(None).build()
    return OwnSetRun(problem.scenarios[0], objective, objective.record(None))


def write_campaign_plots(out_dir: Path, spec: CampaignSpec, painter: Painter) -> bool:
    """``convergence.png`` and ``best_run.png`` (best set against the scenario's own set), drawn
    by ``painter`` after :func:`start_campaign_plots`; True when both were drawn (the painter
    says why otherwise).

    Parameters
    ----------
    out_dir
        Folder of a finished campaign (its ``result.json`` and ``evaluations.jsonl``).
    spec
        The campaign's spec (method, seed, scenarios, plant FMU).
    painter
        The command's painter (:mod:`twin_cosim.painter`), started with the command.
    """
    return painter.draw(f"{__name__}:draw_campaign_figures", Path(out_dir), spec)


def draw_campaign_figures(own: OwnSetRun, out_dir: Path, spec: CampaignSpec) -> None:
    """Draw a campaign's two figures side by side (run by its painter).

    Parameters
    ----------
    own
        The run of the campaign's own set (:func:`run_own_set`).
    out_dir
        The campaign folder: its ``result.json`` and ``evaluations.jsonl`` are read, the figures
        written there.
    spec
        The campaign's spec (method, seed).
    """
    from twin_cosim.painter import draw_side_by_side

    result = json.loads((out_dir / "result.json").read_text())
    best = np.array([result["best_params"][name] for name in own.objective.config.names])
    label = method_label(spec.method)
    title = f"{own.scenario.name}: {label} campaign, seed {spec.seed}"
    try:
        draw_side_by_side(
            partial(plot_convergence, {label: out_dir}, out_dir / "convergence.png"),
            partial(plot_best_run, own, best, label, title, out_dir / "best_run.png"),
        )
    finally:
        own.objective.close()


def plot_best_run(own: OwnSetRun, best: np.ndarray, label: str, title: str, path: Path) -> Path:
    """The run of the best candidate ``best`` (physical units) against the scenario's own set
    (its run ``own``), close-up on the own set's peak error, written to ``path`` (``label``: the
    method's label)."""
    from twin_cosim.plots import plot_error_comparison  # where figures are drawn only

    runs = {
        set_name(own.scenario.tuned): own.record,
        f"best {label}": own.objective.record(best),
    }
    peak = compute_metrics(own.record, own.scenario.metrics_window).t_E_pk
    return plot_error_comparison(runs, peak, title, path)
