"""Figures of optimizer campaigns: convergence and the best run against the reference set."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from twin_cosim.controller import TunedParameters  # noqa: E402
from twin_cosim.metrics import compute_metrics  # noqa: E402
from twin_cosim.optimize.campaign_folder import convergence  # noqa: E402
from twin_cosim.optimize.campaign_spec import CampaignSpec  # noqa: E402
from twin_cosim.plots import plot_error_comparison  # noqa: E402
from twin_cosim.pool_runs import run_records  # noqa: E402
from twin_cosim.scenario import Scenario  # noqa: E402
from twin_cosim.workers import ProcessPool, SerialPool  # noqa: E402


def plot_convergence(campaigns: Mapping[str, Path], path: Path) -> Path:
    """Best E_pk so far against evaluations, one line per campaign folder."""
    fig, ax = plt.subplots(figsize=(8, 5))
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
    plt.close(fig)
    return path


def write_campaign_plots(
    out_dir: Path, spec: CampaignSpec, scenario: Scenario, pool: SerialPool | ProcessPool
) -> None:
    """``convergence.png`` and ``best_run.png`` (best set against the scenario's own set).

    Parameters
    ----------
    out_dir
        Folder of a finished campaign (its ``result.json`` and ``evaluations.jsonl``).
    spec
        The campaign's spec (method, seed, plant FMU).
    scenario
        The campaign's first scenario, resolved (:func:`campaign_scenarios`).
    pool
        Runs the two sets (:mod:`twin_cosim.workers`).
    """
    out_dir = Path(out_dir)
    result = json.loads((out_dir / "result.json").read_text())
    best = TunedParameters(**result["best_params"])
    records = run_records(pool, scenario.plant_fmu(spec.fmu), [(scenario, None), (scenario, best)])
    plot_convergence({spec.method: out_dir}, out_dir / "convergence.png")
    runs = {"scenario set": records[0], f"best {spec.method}": records[1]}
    peak = compute_metrics(runs["scenario set"], scenario.metrics_window).t_E_pk
    plot_error_comparison(
        runs,
        peak,
        f"{scenario.name}: {spec.method} campaign, seed {spec.seed}",
        out_dir / "best_run.png",
    )
