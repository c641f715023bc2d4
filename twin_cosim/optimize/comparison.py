"""``twin compare``: optimizer campaigns on one scenario, the paper's Tables 3-5 for our twin.

A comparison file::

    name: paper-comparison
    scenario: reference1.yaml        # optimized on this (relative to this file, or a shipped
                                     # scenario's name: reference1)
    validation: reference2.yaml      # the optimized sets applied here (Table 5); optional
    methods: [ce, ga, sa, cmaes, de]
    seed: 0
    budgets: {sa: 18000}             # optional per-method evaluation budgets
    plant_parameters: plant.yaml     # optional calibrated plant for every scenario
    robust:                          # optional robust objective (see twin optimize)
      scenarios: [diagnosis.yaml]    #   further scenarios tuned on together with `scenario`
      tolerance: 0.03                #   relative tolerance of the uncertain plant parameters
      samples: 4                     #   plant samples per scenario (the first nominal)
      objective: worst               #   worst or mean over scenarios x samples
      relative: false                #   E_pk relative to the reference set's, case by case
    holdout: [reference2.yaml]       # optional held-out scenarios: one table each

Each method's campaign lives in ``<out>/<method>/`` and is resumed or reused when present, and
so is the AT set (``<out>/autotune.json``).
Writes ``tables.md`` (Table 3: parameters; Table 4: reference metrics, wall time, evaluations;
Table 5: validation metrics; one table per held-out scenario, with what of its motion lies beyond
that of the tuning trajectories (:mod:`twin_cosim.reference`); each with the scenario's own
set, Fine-Tune by default, as "FT", and the industrial baseline of ``twin autotune``, tuned from
the twin's plant FRF, as "AT"),
``tables.json``, ``convergence.png``, ``errors_optimized.png`` and ``errors_validation.png``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim import current_filters
from twin_cosim.controller import TUNED_NAMES
from twin_cosim.controller_set import ControllerSet
from twin_cosim.optimize.algorithms import METHOD_NAMES, method_label
from twin_cosim.optimize.axis_problem import (
    AGGREGATES,
    AxisProblem,
    CampaignSpec,
    controller_set_of,
)
from twin_cosim.optimize.config import check_uncertainty
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.reference import MARGIN, envelope_of, outside
from twin_cosim.report import METRIC_COLUMNS, evaluate_sets, markdown_table, plot_set_errors
from twin_cosim.scenario import Scenario, ScenarioError, load_controller_set, resolve_scenario
from twin_cosim.scenario.loader import find_scenario
from twin_cosim.schema import load_yaml
from twin_cosim.workers import (
    ProcessPool,
    SerialPool,
    autotune_summary,
    make_pool,
    prepare_campaign_worker,
)

if TYPE_CHECKING:
    from twin_cosim.run_record import RunRecord

KEYS = {
    "name",
    "scenario",
    "validation",
    "methods",
    "seed",
    "budgets",
    "plant_parameters",
    "robust",
    "holdout",
}
ROBUST_KEYS = {"scenarios", "tolerance", "samples", "objective", "relative"}


@dataclass(frozen=True)
class Comparison:
    """A checked comparison file."""

    name: str
    scenario: Path
    validation: Path | None
    methods: list[str]
    seed: int = 0
    budgets: dict[str, int] = field(default_factory=dict)
    plant_parameters: Path | None = None
    robust: dict[str, Any] = field(default_factory=dict)
    holdout: list[Path] = field(default_factory=list)


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
    methods = data.get("methods", list(METHOD_NAMES))
    if not isinstance(methods, list) or not methods or any(m not in METHOD_NAMES for m in methods):
        raise ScenarioError(
            f"{path}: methods: expected a list from {list(METHOD_NAMES)}, got {methods!r}"
        )
    budgets = data.get("budgets") or {}
    if not isinstance(budgets, dict) or any(
        m not in METHOD_NAMES or not isinstance(b, int) or b < 1 for m, b in budgets.items()
    ):
        raise ScenarioError(
            f"{path}: budgets: expected method -> positive integer, got {budgets!r}"
        )
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or seed < 0:
        raise ScenarioError(f"{path}: seed: expected a non-negative integer, got {seed!r}")
    validation = data.get("validation")
    here = Path(path).parent
    robust = data.get("robust") or {}
    if not isinstance(robust, dict) or set(robust) - ROBUST_KEYS:
        raise ScenarioError(
            f"{path}: robust: expected a mapping with keys from {sorted(ROBUST_KEYS)}, "
            f"got {robust!r}"
        )
    others = robust.get("scenarios", [])
    if not isinstance(others, list):
        raise ScenarioError(f"{path}: robust.scenarios: expected a list of files, got {others!r}")
    try:
        check_uncertainty(
            robust.get("tolerance", 0.0),
            robust.get("samples", 1),
            ("robust.tolerance", "robust.samples"),
        )
    except ValueError as exc:
        raise ScenarioError(f"{path}: {exc}") from exc
    if robust.get("objective", "worst") not in AGGREGATES:
        raise ScenarioError(f"{path}: robust.objective: expected one of {AGGREGATES}")
    if not isinstance(robust.get("relative", False), bool):
        raise ScenarioError(f"{path}: robust.relative: expected true or false")
    holdout = data.get("holdout") or []
    if not isinstance(holdout, list):
        raise ScenarioError(f"{path}: holdout: expected a list of scenario files, got {holdout!r}")
    calibrated = data.get("plant_parameters")
    return Comparison(
        name=str(data.get("name", Path(path).stem)),
        scenario=_scenario_file(here, data["scenario"]),
        validation=None if validation is None else _scenario_file(here, validation),
        methods=methods,
        seed=seed,
        budgets=budgets,
        plant_parameters=None if calibrated is None else here / str(calibrated),
        robust={
            "scenarios": [str(_scenario_file(here, f)) for f in others],
            "tolerance": float(robust.get("tolerance", 0.0)),
            "samples": int(robust.get("samples", 1)),
            "aggregate": robust.get("objective", "worst"),
            "relative": robust.get("relative", False),
        },
        holdout=[_scenario_file(here, f) for f in holdout],
    )


def _scenario_file(here: Path, given: object) -> Path:
    """A scenario named in a campaign file: a file relative to the campaign file's folder, or
    the name of a shipped scenario (``reference1``), as on the command line."""
    path = here / str(given)
    return path if path.exists() else find_scenario(str(given))


def run_comparison(
    comparison: Comparison,
    out: Path,
    methods: list[str] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    plots: bool = True,
    pool: SerialPool | ProcessPool | None = None,
) -> str:
    """Run (or resume) the campaigns and write the tables, then the figures; returns the Markdown.

    Every campaign, its reference runs and the runs of the tables and figures use one pool:
    ``pool`` (the caller closes it), else one of ``workers`` started here. With ``scheduler``
    the evaluations run on Dask, the other runs in this process.
    """
    methods = methods or comparison.methods
    unknown = [m for m in methods if m not in METHOD_NAMES]
    if unknown:
        raise ValueError(f"unknown methods {unknown}; expected some of {list(METHOD_NAMES)}")
    if pool is None:
        with make_pool(None, 1 if scheduler else workers, prepare_campaign_worker) as own:
            return _compare(comparison, out, methods, scheduler, progress, plots, own)
    return _compare(comparison, out, methods, scheduler, progress, plots, pool)


def _compare(
    comparison: Comparison,
    out: Path,
    methods: list[str],
    scheduler: str | None,
    progress: bool,
    plots: bool,
    pool: SerialPool | ProcessPool,
) -> str:
    """:func:`run_comparison` on ``pool``."""
    out.mkdir(parents=True, exist_ok=True)
    results = _campaigns(comparison, out, methods, scheduler, progress, pool)
    calibrated = _text(comparison.plant_parameters)
    scenario = resolve_scenario(comparison.scenario, calibrated)
    scenarios = {"optimized": scenario}
    if comparison.validation:
        scenarios["validation"] = resolve_scenario(comparison.validation, calibrated)
    for path in comparison.holdout:
        held = resolve_scenario(path, calibrated)
        scenarios[f"holdout {held.name}"] = held
    fmu = scenario.plant_fmu()
    autotuned = _autotuned(pool, fmu, scenario, out / "autotune.json")
    sets = {
        "FT": ControllerSet(scenario.tuned),
        "AT": load_controller_set(str(out / "autotune.json")),
    } | {method_label(m): controller_set_of(results[m]) for m in methods}
    table, records = evaluate_sets(pool, fmu, scenarios, sets)
    import pandas as pd  # the tables written below

    params = pd.DataFrame({name: s.tuned.as_dict() for name, s in sets.items()}).T[
        list(TUNED_NAMES)
    ]
    params.index.name = "method"
    reference = table.loc["optimized"].copy()
    reference["wall [s]"] = ["-", f"{autotuned['wall_s']:.1f}"] + [
        f"{results[m]['wall_s']:.1f}" for m in methods
    ]
    reference["evaluations"] = ["-", "1 FRF"] + [str(results[m]["evaluations"]) for m in methods]
    reference.index.name = "method"
    text = (
        f"# {comparison.name}\n\nOptimized on {scenario.name} with seed {comparison.seed}.\n\n"
        f"## Table 3: optimized parameters\n\n{markdown_table(params)}\n"
        f"{_autotune_note(sets['AT'])}\n"
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
    tuned_on = [scenario.reference] + [
        resolve_scenario(f).reference for f in comparison.robust["scenarios"]
    ]
    beyond = {}
    for label in (k for k in scenarios if k.startswith("holdout ")):
        held = table.loc[label].copy()
        held.index.name = "method"
        text += f"\n## Held out: {scenarios[label].name}\n\n{markdown_table(held)}"
        beyond[scenarios[label].name] = outside(
            envelope_of(scenarios[label].reference), [envelope_of(r) for r in tuned_on]
        )
        if beyond[scenarios[label].name]:
            text += (
                f"\nBeyond the motion of the tuning trajectories (by more than "
                f"{MARGIN:.0%}): {'; '.join(beyond[scenarios[label].name])}.\n"
            )
    (out / "tables.md").write_text(text)
    (out / "tables.json").write_text(
        json.dumps(
            {
                "parameters": params.to_dict(orient="index"),
                "metrics": {f"{s}/{m}": row.to_dict() for (s, m), row in table.iterrows()},
                "campaigns": results,
                "autotune": autotuned,
                "metric_units": METRIC_COLUMNS,
                "holdout_beyond_tuning_motion": beyond,
            },
            indent=2,
        )
        + "\n"
    )
    if plots:
        _plot(out, methods, scenarios, sets, records)
    return text


def _campaigns(
    comparison: Comparison,
    out: Path,
    methods: list[str],
    scheduler: str | None,
    progress: bool,
    pool: SerialPool | ProcessPool,
) -> dict[str, dict[str, Any]]:
    """Each method's campaign result: run, resumed, or read from its folder."""
    results = {}
    for method in methods:
        folder = out / method
        result_path = folder / "result.json"
        if result_path.exists():
            results[method] = json.loads(result_path.read_text())
            continue
        spec = CampaignSpec(
            str(comparison.scenario),
            method,
            comparison.seed,
            comparison.budgets.get(method),
            plant_parameters=_text(comparison.plant_parameters),
            **comparison.robust,
        )
        resume = (folder / "campaign.json").exists()
        problem = AxisProblem.resolve(spec)
        results[method] = run_campaign(
            problem, folder, None, scheduler, resume, progress, pool=pool
        ).as_dict()
    return results


def _plot(
    out: Path,
    methods: list[str],
    scenarios: dict[str, Scenario],
    sets: dict[str, ControllerSet],
    records: dict[tuple[str, str], RunRecord],
) -> None:
    """``convergence.png`` and the error plots of every scenario (``errors_<label>.png``)."""
    from twin_cosim.optimize.outputs import plot_convergence

    plot_convergence({method_label(m): out / m for m in methods}, out / "convergence.png")
    plot_set_errors(
        scenarios,
        sets,
        records,
        "position error per method",
        lambda label, _: out / f"errors_{label.replace(' ', '_')}.png",
    )


def _autotuned(
    pool: SerialPool | ProcessPool, fmu: Path, scenario: Scenario, path: Path
) -> dict[str, Any]:
    """The AT set's summary (``twin autotune``'s layout): read from ``path`` when a comparison
    wrote it before, else tuned by a worker of the pool from the twin's plant FRF and written
    there."""
    if path.is_file():
        return json.loads(path.read_text())
    summary = autotune_summary(pool, fmu, scenario)
    path.write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _autotune_note(controller_set: ControllerSet) -> str:
    """What the AT set changes beyond the six, in words."""
    overrides = controller_set.overrides
    filters = ", ".join(
        f"{f['type']} at {f['frequency_hz']:.4g} Hz"
        for f in map(current_filters.as_dict, overrides["filters"])
    )
    return (
        f"AT (twin autotune, from the twin's plant FRF) also sets the current filters "
        f"({filters or 'none'}) and the feedforwards (velocity and acceleration gain 1, inertia "
        f"{overrides['inertia']:.4g} kg.m2).\n"
    )


def _text(path: Path | None) -> str | None:
    return None if path is None else str(path)
