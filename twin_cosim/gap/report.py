"""The diagnosis report: JSON summary, Markdown and HTML pages.

Its figures are drawn apart, after the pages (:mod:`twin_cosim.gap.figures`).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from twin_cosim.gap.diagnosis import Diagnosis


def _table(rows: list[dict[str, Any]], columns: list[tuple[str, str]]) -> list[list[str]]:
    def cell(value: Any) -> str:
        if isinstance(value, float):
            return f"{value:.4g}"
        if isinstance(value, dict):
            return ", ".join(
                f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in value.items()
            )
        return str(value)

    return [[label for _, label in columns]] + [
        [cell(r.get(key, "")) for key, _ in columns] for r in rows
    ]


RANKING_COLUMNS = [
    ("name", "hypothesis"),
    ("params", "fitted parameters"),
    ("bic", "training BIC"),
    ("holdout_gap_before_um", "held-out RMS before [um]"),
    ("holdout_gap_after_um", "after [um]"),
    ("holdout_current_before_A", "current before [A]"),
    ("holdout_current_after_A", "after [A]"),
    ("holdout_reduction", "reduction"),
    ("passes", "passes"),
]
STEP_COLUMNS = [
    ("effect", "accepted"),
    ("params", "fitted parameters"),
    ("holdout_gap_before_um", "held-out RMS before [um]"),
    ("holdout_gap_after_um", "after [um]"),
    ("holdout_current_before_A", "current before [A]"),
    ("holdout_current_after_A", "after [A]"),
    ("reduction", "normalised reduction"),
]


def _shares_rows(shares: dict[str, dict[str, float]]) -> list[dict[str, Any]]:
    return [{"regime": name, **values} for name, values in shares.items()]


SHARE_COLUMNS = [
    ("regime", "regime"),
    ("time_share", "time share"),
    ("energy_share", "energy share"),
    ("enrichment", "enrichment"),
]


AXIS_COLUMNS = [
    ("from_mm", "from [mm]"),
    ("to_mm", "to [mm]"),
    ("direction", "direction"),
    ("energy_share", "energy share"),
    ("enrichment", "enrichment"),
]
RUN_COLUMNS = [
    ("source", "held-out run"),
    ("position_rms_um_before", "position RMS before [um]"),
    ("position_rms_um_after", "after [um]"),
    ("current_rms_before", "current RMS before"),
    ("current_rms_after", "after"),
    ("relative_errors_before", "relative errors before [%]"),
    ("relative_errors_after", "after [%]"),
    ("pulse_response_before", "acceleration residual after pulse edges, before"),
    ("pulse_response_after", "after"),
]


def _percent(values: dict[str, float]) -> str:
    return " / ".join(f"{100 * v:.2f} %" for v in values.values())


def sections(d: Diagnosis) -> list[tuple[str, str | list[list[str]]]]:
    """The report as (heading, text or table) pairs, shared by Markdown and HTML."""
    summary = d.summary()
    before, after = d.metrics_before[0], d.metrics_after[0]
    figures = d.validation
    accepted = summary["accepted"] or "none"
    parts: list[tuple[str, str | list[list[str]]]] = [
        ("Verdict", f"{d.verdict}. Accepted, in order: {accepted}."),
        ("What is left", d.remaining.text + "."),
        (
            "Data",
            f"Scenario {d.context.scenario.source}; plant model {d.context.model}; measured "
            f"{d.context.measured}; split: {d.context.split}.",
        ),
        (
            "Noise floors",
            f"position {d.floors.sigma_position_m * 1e6:.4g} um ({d.floors.position_source}); "
            f"current {d.floors.sigma_current:.4g} A ({d.floors.current_source}).",
        ),
        (
            "Validation figures (whole run, as in the paper)",
            f"max |gap| {figures['max_um']:.3f} um, mean |gap| {figures['mean_abs_um']:.3f} um, "
            f"RMS {figures['rms_um']:.3f} um. Held-out relative errors of E_pk / ITAE / IAU "
            f"before: {_percent(before.relative_error)}; after: {_percent(after.relative_error)}"
            f" (significant above {_percent(before.threshold)}: "
            f"{d.settings.significance_metric:.0%} plus what noise alone makes). Normalised "
            f"held-out RMS {d.rounds[0].holdout_rms:.3g} (1: noise floor).",
        ),
        ("Held-out runs, before and after", _table(summary["gap"]["holdout_runs"], RUN_COLUMNS)),
        (
            "Where: position residual by regime",
            _table(_shares_rows(d.where.position), SHARE_COLUMNS),
        ),
        (
            "Where: current residual by regime",
            _table(_shares_rows(d.where.current), SHARE_COLUMNS),
        ),
        (
            "Where: along the axis (spans where the residual is concentrated)",
            _table(summary["where"]["along_axis"], AXIS_COLUMNS)
            if d.where.along_axis
            else "The residual is spread evenly along the axis: no span stands out.",
        ),
        (
            "Where: position-periodic or temporal",
            "; ".join(
                f"{k}: {v['verdict']} ({v['reason']})" for k, v in d.where.periodicity.items()
            ),
        ),
        (
            "Which: hypotheses fitted on the training data (first round)",
            _table(summary["effects"], RANKING_COLUMNS),
        ),
        (
            "How far: accepted effects on held-out data",
            _table(summary["steps"], STEP_COLUMNS)
            if summary["steps"]
            else "No effect passed the held-out test.",
        ),
        (
            "Unexplained share of the held-out position residual energy, by regime",
            ", ".join(
                f"{k} {100 * v:.1f} %"
                for k, v in summary["gap"]["unexplained_share_by_regime"].items()
            ),
        ),
        (
            "Noise model (Fourier series at standstill; add to the scenario's plant.parameters)",
            json.dumps(d.noise.plant_parameters)
            + (f"; dropped: {'; '.join(d.noise.dropped)}" if d.noise.dropped else ""),
        ),
        ("Thresholds", json.dumps(summary["thresholds"])),
        ("Warnings", "; ".join(summary["warnings"]) or "none"),
    ]
    return parts


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
        "<title>Gap diagnosis</title></head><body>",
        "<h1>Sim-to-real gap diagnosis</h1>",
    ]
    for heading, body in parts:
        markdown += [f"## {heading}", ""]
        page.append(f"<h2>{html.escape(heading)}</h2>")
        if isinstance(body, str):
            markdown += [body, ""]
            page.append(f"<p>{html.escape(body)}</p>")
        else:
            markdown += ["| " + " | ".join(body[0]) + " |", "|" + "---|" * len(body[0])]
            markdown += ["| " + " | ".join(row) + " |" for row in body[1:]] + [""]
            page.append(
                "<table border='1'>"
                + "".join(
                    "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>"
                    for row in body
                )
                + "</table>"
            )
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
