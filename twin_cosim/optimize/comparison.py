"""``twin compare``: optimizer campaigns on one scenario, the paper's Tables 3-5 for our twin.

A comparison file::

    name: paper-comparison
    scenario: reference1.yaml        # optimized on this (relative to this file)
    validation: reference2.yaml      # the optimized sets applied here (Table 5); optional
    methods: [ce, ga, sa, cmaes, de]
    seed: 0
    budgets: {sa: 18000}             # optional per-method evaluation budgets

Each method's campaign lives in ``<out>/<method>/`` and is resumed or reused when present.
Writes ``tables.md`` (Table 3: parameters; Table 4: reference metrics, wall time, evaluations;
Table 5: validation metrics; each with the scenario's own set, Fine-Tune by default, as "FT"),
``tables.json``, ``convergence.png``, ``errors_optimized.png`` and ``errors_validation.png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.algorithms import ALGORITHMS
from twin_cosim.optimize.campaign import CampaignSpec, run_campaign
from twin_cosim.optimize.outputs import plot_convergence
from twin_cosim.plant import Plant
from twin_cosim.plots import plot_error_comparison
from twin_cosim.report import METRIC_COLUMNS, evaluate_sets, markdown_table
from twin_cosim.scenario import ScenarioError, load_scenario, load_yaml

KEYS = {"name", "scenario", "validation", "methods", "seed", "budgets"}


@dataclass(frozen=True)
class Comparison:
    """A checked comparison file."""

    name: str
    scenario: Path
    validation: Path | None
    methods: list[str]
    seed: int = 0
    budgets: dict[str, int] = field(default_factory=dict)


def load_comparison(path: Path) -> Comparison:
    """Load and check a comparison file; ScenarioError names the file and the key."""
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: expected a mapping with keys {sorted(KEYS)}")
    unknown = sorted(set(data) - KEYS)
    if unknown:
        raise ScenarioError(f"{path}: unknown key(s) {unknown}; allowed: {sorted(KEYS)}")
    if "scenario" not in data:
        raise ScenarioError(f"{path}: scenario: expected the scenario file to optimize on")
    methods = data.get("methods", list(ALGORITHMS))
    if not isinstance(methods, list) or not methods or any(m not in ALGORITHMS for m in methods):
        raise ScenarioError(
            f"{path}: methods: expected a list from {list(ALGORITHMS)}, got {methods!r}"
        )
    budgets = data.get("budgets") or {}
    if not isinstance(budgets, dict) or any(
        m not in ALGORITHMS or not isinstance(b, int) or b < 1 for m, b in budgets.items()
    ):
        raise ScenarioError(
            f"{path}: budgets: expected method -> positive integer, got {budgets!r}"
        )
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"{path}: seed: expected a non-negative integer, got {seed!r}")
    validation = data.get("validation")
    return Comparison(
        name=str(data.get("name", Path(path).stem)),
        scenario=Path(path).parent / str(data["scenario"]),
        validation=None if validation is None else Path(path).parent / str(validation),
        methods=methods,
        seed=seed,
        budgets=budgets,
    )


def run_comparison(
    comparison: Comparison,
    out: Path,
    methods: list[str] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
) -> str:
    """Run (or resume) the campaigns and write the tables and figures; returns the Markdown."""
    methods = methods or comparison.methods
    unknown = [m for m in methods if m not in ALGORITHMS]
    if unknown:
        raise ValueError(f"unknown methods {unknown}; expected some of {list(ALGORITHMS)}")
    out.mkdir(parents=True, exist_ok=True)
    results = {}
    for method in methods:
        folder = out / method
        result_path = folder / "result.json"
        if result_path.exists():
            results[method] = json.loads(result_path.read_text())
            continue
        spec = CampaignSpec(
            str(comparison.scenario), method, comparison.seed, comparison.budgets.get(method)
        )
        resume = (folder / "campaign.json").exists()
        results[method] = run_campaign(spec, folder, workers, scheduler, resume, progress).as_dict()
    scenario = load_scenario(comparison.scenario)
    sets = {"FT": scenario.tuned} | {
        m.upper(): TunedParameters(**results[m]["best_params"]) for m in methods
    }
    scenarios = {"optimized": scenario}
    if comparison.validation:
        scenarios["validation"] = load_scenario(comparison.validation)
    with Plant(scenario.fmu) as plant:
        table, records = evaluate_sets(plant, scenarios, sets)
    params = pd.DataFrame({name: tuned.as_dict() for name, tuned in sets.items()}).T[
        list(TUNED_NAMES)
    ]
    params.index.name = "method"
    reference = table.loc["optimized"].copy()
    reference["wall [s]"] = ["-"] + [f"{results[m]['wall_s']:.1f}" for m in methods]
    reference["evaluations"] = ["-"] + [str(results[m]["evaluations"]) for m in methods]
    reference.index.name = "method"
    text = (
        f"# {comparison.name}\n\nOptimized on {scenario.name} with seed {comparison.seed}.\n\n"
        f"## Table 3: optimized parameters\n\n{markdown_table(params)}\n"
        f"## Table 4: {scenario.name}\n\n{markdown_table(reference)}\n"
    )
    if comparison.validation:
        validation = table.loc["validation"].copy()
        validation.index.name = "method"
        text += (
            f"## Table 5: {scenarios['validation'].name} with the parameters tuned on "
            f"{scenario.name}\n\n"
        )
        text += markdown_table(validation)
    (out / "tables.md").write_text(text)
    (out / "tables.json").write_text(
        json.dumps(
            {
                "parameters": params.to_dict(orient="index"),
                "metrics": {f"{s}/{m}": row.to_dict() for (s, m), row in table.iterrows()},
                "campaigns": results,
                "metric_units": METRIC_COLUMNS,
            },
            indent=2,
        )
        + "\n"
    )
    plot_convergence({m: out / m for m in methods}, out / "convergence.png")
    for label, s in scenarios.items():
        runs = {name: records[(label, name)] for name in sets}
        peak = compute_metrics(runs["FT"], s.metrics_window).t_E_pk
        plot_error_comparison(
            runs, peak, f"{s.name}: position error per method", out / f"errors_{label}.png"
        )
    return text
