"""Tables of results: several parameter sets on several scenarios, as Markdown and CSV."""

from __future__ import annotations

from collections.abc import Mapping

import pandas as pd

from twin_cosim.controller_set import ControllerSet
from twin_cosim.cosim import run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.plant import Plant
from twin_cosim.scenario import Scenario, with_controller_set

METRIC_COLUMNS = {
    "E_pk_um": "E_pk [um]",
    "ITAE": "ITAE [um.s^2]",
    "IAU": "IAU [A.s]",
    "rms_um": "RMS [um]",
}


def markdown_table(frame: pd.DataFrame, float_format: str = "{:.4g}") -> str:
    """A GitHub-flavoured Markdown table of ``frame`` (index included as the first column)."""
    header = [frame.index.name or ""] + [str(c) for c in frame.columns]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for index, row in frame.iterrows():
        cells = [float_format.format(v) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join([str(index), *cells]) + " |")
    return "\n".join(lines) + "\n"


def evaluate_sets(
    plant: Plant, scenarios: Mapping[str, Scenario], sets: Mapping[str, ControllerSet]
) -> tuple[pd.DataFrame, dict[tuple[str, str], pd.DataFrame]]:
    """Run every controller set (the six and any settings it changes) on every scenario.

    Parameters
    ----------
    plant
        The plant to step.
    scenarios
        Scenarios by label.
    sets
        Controller sets by name.

    Returns
    -------
    tuple
        A table with one row per (scenario label, set) and the metric columns, and the run
        records keyed by (scenario label, set name).
    """
    rows, records = [], {}
    for label, scenario in scenarios.items():
        for name, controller_set in sets.items():
            record = run_scenario(plant, with_controller_set(scenario, controller_set))
            metrics = compute_metrics(record, scenario.metrics_window)
            records[(label, name)] = record
            rows.append(
                {
                    "scenario": label,
                    "set": name,
                    **{label: getattr(metrics, key) for key, label in METRIC_COLUMNS.items()},
                }
            )
    return pd.DataFrame(rows).set_index(["scenario", "set"]), records
