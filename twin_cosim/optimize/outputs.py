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

from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.campaign_folder import convergence
from twin_cosim.optimize.campaign_spec import CampaignSpec, controller_set_of
from twin_cosim.scenario import Scenario, with_controller_set
from twin_cosim.workers import ProcessPool, SerialPool


def plot_convergence(campaigns: Mapping[str, Path], path: Path) -> Path:
    """Best E_pk so far against evaluations, one line per campaign folder."""
    from matplotlib.figure import Figure  # where figures are drawn only

    fig = Figure(figsize=(8, 5))
    ax = fig.subplots()
    for label, folder in campaigns.items():
        best = convergence(folder)
        ax.plot(range(1, len(best) + 1), best, label=label)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("evaluations")
    ax.set_ylabel("best fitness so far [um] (E_pk; penalties above 1e6)")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
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
    title = f"{scenario.name}: {spec.method} campaign, seed {spec.seed}"
    tasks = [
        ConvergenceFigure(spec.method, out_dir),
        BestRunFigure(scenario, best, spec.method, title, out_dir / "best_run.png"),
    ]
    list(pool.imap(tasks, CampaignFigures(str(scenario.plant_fmu(spec.fmu)))))


@dataclass(frozen=True)
class ConvergenceFigure:
    """Task: ``convergence.png`` of the campaign folder ``out_dir`` of ``method``."""

    method: str
    out_dir: Path

    def draw(self, worker: CampaignFigureWorker) -> Path:
        """Draw it; the written path."""
        return plot_convergence({self.method: self.out_dir}, self.out_dir / "convergence.png")


@dataclass(frozen=True)
class BestRunFigure:
    """Task: the best set's run against the scenario's own set (``best`` is the scenario with
    the best set), close-up on the own set's peak, written to ``path``."""

    scenario: Scenario
    best: Scenario
    method: str
    title: str
    path: Path

    def draw(self, worker: CampaignFigureWorker) -> Path:
        """Run both sets on the worker's plant and draw them; the written path."""
        from twin_cosim.plots import plot_error_comparison  # where figures are drawn only

        runs = {
            "scenario set": worker.record(self.scenario),
            f"best {self.method}": worker.record(self.best),
        }
        peak = compute_metrics(runs["scenario set"], self.scenario.metrics_window).t_E_pk
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
        self.plant = None

    def record(self, scenario: Scenario):  # noqa: ANN201 - a pandas DataFrame
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
