"""Figures of optimizer campaigns: convergence and the best run against the reference set.

A campaign's two figures are drawn by its pool's workers, side by side (the best run's records
made where they are drawn), while the parent, which loads neither the plant nor matplotlib,
waits.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.campaign_folder import logged_fitness
from twin_cosim.optimize.campaign_spec import CampaignSpec, controller_set_of
from twin_cosim.optimize.methods import method_label
from twin_cosim.paper import set_name
from twin_cosim.scenario import Scenario, with_controller_set
from twin_cosim.workers import ProcessPool, SerialPool

if TYPE_CHECKING:
    import pandas as pd

    from twin_cosim.plant import Plant

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
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def write_campaign_plots(
    out_dir: Path, spec: CampaignSpec, scenario: Scenario, pool: SerialPool | ProcessPool
) -> None:
    """``convergence.png`` and ``best_run.png`` (best set against the scenario's own set), each
    drawn by a worker of ``pool``.

    Parameters
    ----------
    out_dir
        Folder of a finished campaign (its ``result.json`` and ``evaluations.jsonl``).
    spec
        The campaign's spec (method, seed, plant FMU).
    scenario
        The campaign's first scenario, resolved (:func:`campaign_scenarios`).
    pool
        Draws the figures and runs the two sets (:mod:`twin_cosim.workers`).
    """
    out_dir = Path(out_dir)
    result = json.loads((out_dir / "result.json").read_text())
    best = with_controller_set(scenario, controller_set_of(result))
    label = method_label(spec.method)
    title = f"{scenario.name}: {label} campaign, seed {spec.seed}"
    tasks = [
        ConvergenceFigure(label, out_dir),
        BestRunFigure(scenario, best, label, title, out_dir / "best_run.png"),
    ]
    list(pool.imap(tasks, CampaignFigures(str(scenario.plant_fmu(spec.fmu)))))


@dataclass(frozen=True)
class ConvergenceFigure:
    """Task: ``convergence.png`` of the campaign folder ``out_dir`` of ``method`` (its label)."""

    method: str
    out_dir: Path

    def draw(self, worker: CampaignFigureWorker) -> Path:
        """Draw it; the written path."""
        return plot_convergence({self.method: self.out_dir}, self.out_dir / "convergence.png")


@dataclass(frozen=True)
class BestRunFigure:
    """Task: the best set's run against the scenario's own set (``best`` is the scenario with
    the best set), close-up on the own set's peak, written to ``path``; ``method`` is the
    method's label."""

    scenario: Scenario
    best: Scenario
    method: str
    title: str
    path: Path

    def draw(self, worker: CampaignFigureWorker) -> Path:
        """Run both sets on the worker's plant and draw them; the written path."""
        from twin_cosim.plots import plot_error_comparison  # where figures are drawn only

        own = set_name(self.scenario.tuned)
        runs = {own: worker.record(self.scenario), f"best {self.method}": worker.record(self.best)}
        peak = compute_metrics(runs[own], self.scenario.metrics_window).t_E_pk
        return plot_error_comparison(runs, peak, self.title, self.path)


@dataclass(frozen=True)
class CampaignFigures:
    """The recipe of a :class:`CampaignFigureWorker`: the FMU its plant loads."""

    fmu: str

    def build(self) -> CampaignFigureWorker:
        """The worker, in the process that runs it."""
        return CampaignFigureWorker(self.fmu)


class CampaignFigureWorker:
    """A worker drawing a campaign's figures; its plant is loaded at the first run a figure
    needs."""

    def __init__(self, fmu: str) -> None:
        self.fmu = fmu
        self.plant: Plant | None = None

    def record(self, scenario: Scenario) -> pd.DataFrame:
        """The record of ``scenario`` run with its own set on this worker's plant."""
        from twin_cosim.cosim import run_scenario
        from twin_cosim.plant import Plant

        if self.plant is None:
            self.plant = Plant(self.fmu)
        return run_scenario(self.plant, scenario)

    def __call__(self, task: ConvergenceFigure | BestRunFigure) -> Path:
        """Draw the figure ``task``; its path."""
        return task.draw(self)

    def close(self) -> None:
        """Free the plant, if loaded."""
        if self.plant is not None:
            self.plant.close()
