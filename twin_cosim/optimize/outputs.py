"""Figures of optimizer campaigns: convergence and the best run against the reference set."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import FuncFormatter  # noqa: E402

from twin_cosim.metrics import compute_metrics  # noqa: E402
from twin_cosim.optimize.campaign_folder import logged_fitness  # noqa: E402
from twin_cosim.optimize.campaign_spec import CampaignSpec, controller_set_of  # noqa: E402
from twin_cosim.optimize.methods import method_label  # noqa: E402
from twin_cosim.paper import set_name  # noqa: E402
from twin_cosim.plots import plot_error_comparison  # noqa: E402
from twin_cosim.pool_runs import run_records  # noqa: E402
from twin_cosim.scenario import Scenario, with_controller_set  # noqa: E402
from twin_cosim.workers import ProcessPool, SerialPool  # noqa: E402

PLAIN = FuncFormatter(lambda value, _: f"{value:g}")  # 20, not 2 x 10^1
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
    fig, (ax, apart) = plt.subplots(
        2, 1, figsize=(9, 7), sharex=True, gridspec_kw={"height_ratios": [4, 1.3]}
    )
    labels = []
    for row, (label, folder) in enumerate(campaigns.items()):
        fitness, status = logged_fitness(folder)
        evaluation = np.arange(1, len(fitness) + 1)
        valid = np.array([s == "ok" for s in status], dtype=bool)
        labels.append(f"{label} ({len(status) - valid.sum()} of {len(status)})")
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
    ax.set_yscale("log")
    for axis in (ax.yaxis, ax.xaxis):
        axis.set_major_formatter(PLAIN)
    ax.yaxis.set_minor_formatter(PLAIN)
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
    best = with_controller_set(scenario, controller_set_of(result))
    records = run_records(pool, scenario.plant_fmu(spec.fmu), [(scenario, None), (best, None)])
    label = method_label(spec.method)
    plot_convergence({label: out_dir}, out_dir / "convergence.png")
    own = set_name(scenario.tuned)
    runs = {own: records[0], f"best {label}": records[1]}
    peak = compute_metrics(runs[own], scenario.metrics_window).t_E_pk
    plot_error_comparison(
        runs,
        peak,
        f"{scenario.name}: {label} campaign, seed {spec.seed}",
        out_dir / "best_run.png",
    )
