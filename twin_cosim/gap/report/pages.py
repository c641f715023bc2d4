"""The diagnosis report: JSON summary, Markdown and HTML pages.

Its figures are drawn apart, after the pages (:mod:`twin_cosim.gap.report.figures`).
"""

from __future__ import annotations

import html
import json
import re
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim.gap.data.context import library_for
from twin_cosim.gap.data.regimes import energy_shares
from twin_cosim.gap.report.verdict import (
    STROKE_END,
    gap_table,
    names,
    number,
    parameters,
    percent,
    quantity,
)
from twin_cosim.plant_model import plant_model

if TYPE_CHECKING:
    from twin_cosim.gap.diagnosis import Diagnosis


Row = dict[str, Any]
Column = tuple[str, str, Callable[[Any, Row], str]]


def _table(rows: list[Row], columns: list[Column]) -> list[list[str]]:
    """Header and cells, each cell written by its column's formatter (value, row)."""
    return [[label for _, label, _ in columns]] + [
        [show(row.get(key), row) for key, _, show in columns] for row in rows
    ]


def _num(value: Any, _row: Row) -> str:
    return number(value)


def _pct(value: Any, _row: Row) -> str:
    return percent(value)


def _text(value: Any, _row: Row) -> str:
    return "-" if value is None else str(value).replace("_", " ")


def _yes(value: Any, _row: Row) -> str:
    return "yes" if value else "no"


def _signed(value: Any, _row: Row) -> str:
    return {1: "+", -1: "-", 0: "both"}.get(value, "-")


def _effect(value: Any, _row: Row) -> str:
    return names([value]) if value is not None else "-"


def _fitted(units: dict[str, dict[str, str]], name_key: str) -> Callable[[Any, Row], str]:
    """A formatter of a row's fitted parameters with the units of its hypothesis."""

    def show(value: Any, row: Row) -> str:
        return parameters(value or {}, units.get(str(row.get(name_key)), {}))

    return show


def _ranking_columns(units: dict[str, dict[str, str]]) -> list[Column]:
    return [
        ("name", "hypothesis", _text),
        ("params", "fitted parameters", _fitted(units, "name")),
        ("bic", "training BIC", _num),
        ("holdout_gap_after_um", "held-out position RMS with it [um]", _num),
        ("holdout_current_after_A", "held-out current RMS with it [A]", _num),
        ("holdout_reduction", "reduction of the normalised RMS", _pct),
        ("evidence_z", "evidence z", _num),
        ("critical_z", "needed z", _num),
        ("passes", "passes", _yes),
    ]


def _step_columns(units: dict[str, dict[str, str]]) -> list[Column]:
    return [
        ("effect", "accepted", _effect),
        ("params", "fitted parameters (its round)", _fitted(units, "fitted")),
        ("holdout_gap_before_um", "held-out position RMS before it [um]", _num),
        ("holdout_gap_after_um", "with it, as fitted in its round [um]", _num),
        ("holdout_current_before_A", "held-out current RMS before it [A]", _num),
        ("holdout_current_after_A", "with it, as fitted in its round [A]", _num),
        ("reduction", "reduction of the normalised RMS", _pct),
    ]


SHARE_COLUMNS: list[Column] = [
    ("regime", "regime", _text),
    ("time_share", "share of the time [%]", _pct),
    ("energy_share", "share of the residual energy [%]", _pct),
    ("enrichment", "energy share over time share [x]", _num),
]
AXIS_COLUMNS: list[Column] = [
    ("from_mm", "from [mm]", _num),
    ("to_mm", "to [mm]", _num),
    ("direction", "direction of motion", _signed),
    ("at_stroke_end", STROKE_END, _yes),
    ("energy_share", "share of the energy above the even level [%]", _pct),
    ("enrichment", "peak energy over the even level [x]", _num),
]


def _errors(value: Any, _row: Row) -> str:
    return ", ".join(f"{k} {percent(v / 100.0)}" for k, v in (value or {}).items()) or "-"


def _pulses(value: Any, _row: Row) -> str:
    if not value:
        return "-"
    return (
        f"{value['edges']} edges: {percent(value['energy_share'])} of the energy in "
        f"{percent(value['time_share'])} of the time, ringing at {number(value['ringing_hz'])} Hz"
    )


def _run_columns(runs: list[Row]) -> list[Column]:
    columns: list[Column] = [
        ("source", "held-out run", _text),
        ("position_rms_um_before", "position RMS before [um]", _num),
        ("position_rms_um_after", "after [um]", _num),
        ("current_rms_before", "current RMS before [A]", _num),
        ("current_rms_after", "after [A]", _num),
        ("relative_errors_before", "relative errors before", _errors),
        ("relative_errors_after", "after", _errors),
    ]
    if any(r.get("pulse_response_before") for r in runs):
        columns += [
            ("pulse_response_before", "acceleration residual after pulse edges, before", _pulses),
            ("pulse_response_after", "after", _pulses),
        ]
    return columns


def _shares_rows(shares: dict[str, dict[str, float]]) -> list[Row]:
    return [{"regime": name, **values} for name, values in shares.items()]


def hypothesis_units(model: str) -> dict[str, dict[str, str]]:
    """Unit of each fitted parameter, per hypothesis of the model's library."""
    return {h.name: {p.name: p.unit for p in h.parameters} for h in library_for(model)}


def _parameter_units(model: str) -> dict[str, str]:
    """Unit of each FMU parameter of the model."""
    return {name: v.unit or "" for name, v in plant_model(model).parameters.items()}


def _metrics(values: dict[str, float]) -> str:
    return " / ".join(percent(v) for v in values.values())


def _setting(name: str, value: Any) -> str:
    """A setting as a person reads it: ``0.5``, ``500 um``, ``the whole library``."""
    if value is None:
        return "the whole library"
    if isinstance(value, (tuple, list)):
        return ", ".join(str(v) for v in value)
    if name in SETTING_UNITS:
        return quantity(value, SETTING_UNITS[name])
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


SETTING_UNITS = {"axis_bin": "m"}


def sections(d: Diagnosis) -> list[tuple[str, str | list[list[str]]]]:
    """The report as (heading, text or table) pairs, shared by Markdown and HTML.

    Every number is written for people (:mod:`twin_cosim.gap.report.verdict`); the verdict is
    followed by the table that holds each of its numbers (:func:`gap_table`).
    """
    summary = d.summary()
    units = hypothesis_units(d.context.model)
    before, after = d.metrics_before[0], d.metrics_after[0]
    figures = d.validation
    verdict = f"{d.verdict}."
    if d.remaining.text not in d.verdict:
        verdict += f" {d.remaining.text[0].upper()}{d.remaining.text[1:]}."
    verdict += f" Accepted, in order: {names(summary['accepted'])}."
    before_shares = energy_shares(d.holdout_before.position, d.holdout_before.regimes)
    noise = parameters(d.noise.plant_parameters, _parameter_units(d.context.model))
    parts: list[tuple[str, str | list[list[str]]]] = [
        ("Verdict", verdict),
        (
            "The verdict's figures: the held-out gap before and after the accepted effects "
            "(after: all accepted effects refitted together with the calibrated parameters)",
            gap_table(d.remaining, before_shares, d.remaining_where),
        ),
        (
            "Data",
            f"Scenario {d.context.scenario.source}; plant model {d.context.model}; measured "
            f"{', '.join(d.context.measured)}; split: {d.context.split}.",
        ),
        (
            "Noise floors",
            f"position {quantity(d.floors.sigma_position_m, 'm')} ({d.floors.position_source}); "
            f"current {quantity(d.floors.sigma_current, 'A')} ({d.floors.current_source}).",
        ),
        (
            "Validation figures (training and held-out data before the accepted effects, as in "
            "the paper)",
            f"max |gap| {number(figures['max_um'])} um, mean |gap| "
            f"{number(figures['mean_abs_um'])} um, RMS {number(figures['rms_um'])} um. Held-out "
            f"relative errors of E_pk / ITAE / IAU before: {_metrics(before.relative_error)}; "
            f"after: {_metrics(after.relative_error)} (significant above "
            f"{_metrics(before.threshold)}: {percent(d.settings.significance_metric)} plus what "
            "noise alone makes).",
        ),
        (
            "Held-out runs, before and after the accepted effects",
            _table(summary["gap"]["holdout_runs"], _run_columns(summary["gap"]["holdout_runs"])),
        ),
        (
            "Where the gap lies before the accepted effects (training and held-out data): "
            "position residual by regime",
            _table(_shares_rows(d.where.position), SHARE_COLUMNS),
        ),
        (
            "Before the accepted effects: current residual by regime",
            _table(_shares_rows(d.where.current), SHARE_COLUMNS),
        ),
        (
            "Before the accepted effects: spans along the axis where the residual is concentrated",
            _table([asdict(s) for s in d.where.along_axis], AXIS_COLUMNS)
            if d.where.along_axis
            else "The residual is spread evenly along the axis: no span stands out.",
        ),
        (
            "After the accepted effects (held-out data): spans along the axis",
            _table([asdict(s) for s in d.remaining_where.along_axis], AXIS_COLUMNS)
            if d.remaining_where.along_axis
            else "What is left is spread evenly along the axis: no span stands out.",
        ),
        (
            "Before the accepted effects: position-periodic or temporal",
            "; ".join(
                f"{k.replace('_', ' ')}: {v['verdict']} ({v['reason']})"
                for k, v in d.where.periodicity.items()
            ),
        ),
        (
            "Which: hypotheses fitted on the training data, judged on the held-out data (first "
            f"round; held-out position RMS before {number(d.rounds[0].position_rms_um)} um, "
            f"current {number(d.rounds[0].current_rms)} A)",
            _table(summary["effects"], _ranking_columns(units)),
        ),
        (
            "How far: each accepted effect on the held-out data, as fitted in its round",
            _table(summary["steps"], _step_columns(units))
            if summary["steps"]
            else "No effect passed the held-out test.",
        ),
        (
            "Share of the held-out position gap energy left after the accepted effects, by regime",
            ", ".join(
                f"{k.replace('_', ' ')} {percent(v)}"
                for k, v in summary["gap"]["unexplained_share_by_regime"].items()
            ),
        ),
        (
            "Noise model (Fourier series at standstill; add to the scenario's plant.parameters)",
            ("none identified" if noise == "-" else noise)
            + (f"; dropped: {'; '.join(d.noise.dropped)}" if d.noise.dropped else ""),
        ),
        (
            "Thresholds (DiagnosisSettings; the scenario's diagnose: section)",
            [["setting", "value"]] + [[k, _setting(k, v)] for k, v in asdict(d.settings).items()],
        ),
        ("Warnings", "; ".join(summary["warnings"]) or "none"),
    ]
    return parts


STYLE = (
    "body{font-family:sans-serif;max-width:72em;margin:1em auto;padding:0 1em;line-height:1.4}"
    "h2{font-size:1.1em;margin-top:1.6em}"
    "table{border-collapse:collapse;font-size:0.9em}"
    "th,td{border:1px solid #bbb;padding:0.2em 0.5em;vertical-align:top}"
    "th{background:#eee;text-align:left}td.n{text-align:right;white-space:nowrap}"
    ".verdict{background:#f4f4f4;border-left:4px solid #555;padding:0.6em 0.8em}"
    "img{max-width:100%}"
)
NUMERIC = re.compile(r"^(-|[-+]?\d[\d.e+-]*( %)?|yes|no)$")


def _html_table(rows: list[list[str]]) -> str:
    """A table: a header row, then cells; numbers right-aligned."""
    header = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join(
        "<tr>"
        + "".join(f"<td{' class=n' if NUMERIC.match(c) else ''}>{html.escape(c)}</td>" for c in row)
        + "</tr>"
        for row in rows[1:]
    )
    return f"<table><tr>{header}</tr>{body}</table>"


FIGURES = ("residuals.png", "regimes.png", "along_axis.png", "spectra.png", "ranking.png")


def write_report(
    d: Diagnosis, out: Path, extra: dict[str, Any] | None = None, figures: bool = True
) -> dict[str, str]:
    """Write diagnosis.json (the summary and ``extra``), report.md and report.html into ``out``.

    The pages show :data:`FIGURES` when ``figures`` (written apart, after the pages:
    :func:`twin_cosim.gap.figures.write_figures`).
    """
    out.mkdir(parents=True, exist_ok=True)
    summary = {**d.summary(), **(extra or {})}
    (out / "diagnosis.json").write_text(json.dumps(summary, indent=2) + "\n")
    parts = sections(d)
    markdown = ["# Sim-to-real gap diagnosis", ""]
    page = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>Gap diagnosis</title><style>{STYLE}</style></head><body>",
        "<h1>Sim-to-real gap diagnosis</h1>",
    ]
    for index, (heading, body) in enumerate(parts):
        markdown += [f"## {heading}", ""]
        page.append(f"<h2>{html.escape(heading)}</h2>")
        if isinstance(body, str):
            markdown += [body, ""]
            page.append(f"<p{' class=verdict' if index == 0 else ''}>{html.escape(body)}</p>")
        else:
            markdown += ["| " + " | ".join(body[0]) + " |", "|" + "---|" * len(body[0])]
            markdown += ["| " + " | ".join(row) + " |" for row in body[1:]] + [""]
            page.append(_html_table(body))
    if figures:
        markdown += ["## Figures", ""] + [f"![{name}]({name})" for name in FIGURES] + [""]
        page += ["<h2>Figures</h2>"]
        page += [f"<p><img src='{name}' alt='{name}'></p>" for name in FIGURES]
    page.append("</body></html>")
    (out / "report.md").write_text("\n".join(markdown))
    (out / "report.html").write_text("\n".join(page) + "\n")
    return {
        "json": str(out / "diagnosis.json"),
        "markdown": str(out / "report.md"),
        "html": str(out / "report.html"),
    }
