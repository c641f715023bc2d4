"""Tables of results: several parameter sets on several scenarios, as Markdown and CSV; short
text tables of a command's figures with their units."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import pandas as pd

from twin_cosim.metrics import compute_metrics
from twin_cosim.scenario import with_controller_set
from twin_cosim.workers import run_records

if TYPE_CHECKING:
    from twin_cosim.controller_set import ControllerSet
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario
    from twin_cosim.workers import ProcessPool, SerialPool

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


def text_table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    """Rows of text cells as left-aligned columns under a header and a rule (a command's
    ``.txt`` table: name each quantity's unit in a column or in its name)."""
    widths = [max(len(row[i]) for row in (header, *rows)) for i in range(len(header))]

    def line(row: tuple[str, ...]) -> str:
        return "  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()

    head = line(header)
    return "\n".join([head, "-" * len(head), *(line(row) for row in rows)]) + "\n"


def evaluate_sets(
    pool: SerialPool | ProcessPool,
    fmu: Path,
    scenarios: Mapping[str, Scenario],
    sets: Mapping[str, ControllerSet],
) -> tuple[pd.DataFrame, dict[tuple[str, str], RunRecord]]:
    """Run every controller set (the six and any settings it changes) on every scenario, on the
    pool's workers.

    Parameters
    ----------
    pool
        The workers (:mod:`twin_cosim.workers`); a :class:`~twin_cosim.workers.SerialPool`
        runs in this process.
    fmu
        The plant FMU of every run.
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
    keys = [(label, name) for label in scenarios for name in sets]
    tasks = [(with_controller_set(scenarios[label], sets[name]), None) for label, name in keys]
    records = dict(zip(keys, run_records(pool, fmu, tasks), strict=True))
    rows = []
    for label, name in keys:
        metrics = compute_metrics(records[(label, name)], scenarios[label].metrics_window)
        rows.append(
            {
                "scenario": label,
                "set": name,
                **{column: getattr(metrics, key) for key, column in METRIC_COLUMNS.items()},
            }
        )
    return pd.DataFrame(rows).set_index(["scenario", "set"]), records


def plot_set_errors(
    scenarios: Mapping[str, Scenario],
    sets: Mapping[str, ControllerSet],
    records: Mapping[tuple[str, str], RunRecord],
    title: str,
    path_of: Callable[[str, Scenario], Path],
) -> None:
    """One plot per scenario: the position error (um) of every set, around the Fine-Tune set's
    peak (the sets hold ``FT``).

    Parameters
    ----------
    scenarios, sets, records
        As :func:`evaluate_sets` takes and returns them.
    title
        What the sets are, after the scenario's name.
    path_of
        The PNG file of a scenario, from its label and the scenario.
    """
    from twin_cosim.plots import plot_error_comparison  # matplotlib: not at start

    for label, scenario in scenarios.items():
        runs = {name: records[(label, name)] for name in sets}
        peak = compute_metrics(runs["FT"], scenario.metrics_window).t_E_pk
        plot_error_comparison(runs, peak, f"{scenario.name}: {title}", path_of(label, scenario))
