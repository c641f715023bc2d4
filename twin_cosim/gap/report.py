"""The diagnosis report: JSON summary, Markdown and HTML pages, figures."""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from twin_cosim.gap import regimes as regime_model  # noqa: E402
from twin_cosim.gap import spectra  # noqa: E402
from twin_cosim.gap.diagnosis import Diagnosis  # noqa: E402
from twin_cosim.gap.residuals import joined  # noqa: E402
from twin_cosim.metrics import UM_PER_M  # noqa: E402

REGIME_COLOURS = {
    "standstill": "#dddddd",
    "breakaway": "#f4a582",
    "acceleration": "#92c5de",
    "constant_velocity": "#ffffff",
    "reversal": "#d6604d",
}


def _shade_regimes(ax, t: np.ndarray, labels: np.ndarray) -> None:
    for code, name in enumerate(regime_model.REGIMES):
        if name == "constant_velocity":
            continue
        for start, stop in regime_model.segments(labels, code):
            ax.axvspan(
                t[start], t[min(stop, len(t) - 1)], color=REGIME_COLOURS[name], alpha=0.5, lw=0
            )


def plot_residuals(d: Diagnosis, path: Path) -> Path:
    """Position and current residuals over time, regimes shaded, before and after the effects."""
    fig, axes = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    for res, label, style in (
        (d.train_before, "before (training)", "-"),
        (d.holdout_before, "before (held out)", "-"),
        (d.holdout_after, "after the accepted effects (held out)", "-"),
    ):
        axes[0].plot(res.t, res.position * UM_PER_M, style, lw=0.7, label=label)
        axes[1].plot(res.t, res.current, style, lw=0.7, label=label)
    for ax in axes:
        _shade_regimes(ax, d.train_before.t, d.train_before.regimes)
        _shade_regimes(ax, d.holdout_before.t, d.holdout_before.regimes)
        ax.axvline(d.context.train_end, color="k", ls="--", lw=1)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_ylabel("position residual [um]")
    axes[1].set_ylabel("current residual [A]")
    axes[1].set_xlabel(
        "t [s]  (shading: standstill grey, breakaway orange, acceleration blue, reversal red)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_regimes(d: Diagnosis, path: Path) -> Path:
    """Share of residual energy against share of time per regime."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    names = list(regime_model.REGIMES)
    x = np.arange(len(names))
    for ax, signal in zip(axes, ("position", "current"), strict=True):
        shares = getattr(d.where, signal)
        ax.bar(x - 0.2, [shares[n]["time_share"] for n in names], 0.4, label="time share")
        ax.bar(
            x + 0.2, [shares[n]["energy_share"] for n in names], 0.4, label="residual energy share"
        )
        ax.set_xticks(x, [n.replace("_", "\n") for n in names], fontsize=8)
        ax.set_title(f"{signal} residual")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_spectra(d: Diagnosis, path: Path) -> Path:
    """Residual spectra: in Hz, and in orders of the motor and screw angle (constant velocity)."""
    res = d.train_before
    dt = float(np.median(np.diff(res.t)))
    stretches = regime_model.segments(res.regimes, regime_model.REGIMES.index("constant_velocity"))
    fig, axes = plt.subplots(3, 2, figsize=(11, 9))
    for column, (signal, values, unit) in enumerate(
        (("position", res.position * UM_PER_M, "um"), ("current", res.current, "A"))
    ):
        f, a = spectra.frequency_spectrum(values, dt)
        axes[0, column].semilogy(f[1:], a[1:] + 1e-12, lw=0.7)
        axes[0, column].set_xlabel("frequency [Hz]")
        for row, (angle_name, angle) in enumerate(
            (("motor", res.motor_angle), ("screw", d.context.screw_angle(res.motor_angle))), start=1
        ):
            orders, amplitude = spectra.order_spectrum(values, angle, stretches)
            if len(orders):
                axes[row, column].semilogy(orders[1:], amplitude[1:] + 1e-12, lw=0.8)
            axes[row, column].set_xlabel(f"order of the {angle_name} angle [cycles/rev]")
        for row in range(3):
            axes[row, column].set_ylabel(f"{signal} residual [{unit}]")
            axes[row, column].grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_ranking(d: Diagnosis, path: Path) -> Path:
    """Evidence of each hypothesis (first round) beyond the noise, with the acceptance line."""
    rows = d.rounds[0].candidates
    fig, ax = plt.subplots(figsize=(9, 4))
    if rows:
        ax.barh([c.name for c in rows], [max(c.evidence_z, 0.0) for c in rows])
        ax.axvline(rows[0].critical_z, color="r", ls="--", label="acceptance")
        ax.set_xscale("symlog", linthresh=1.0)
        ax.invert_yaxis()
        ax.legend()
    ax.set_xlabel(
        "held-out evidence z beyond calibration and noise (listed by training BIC, best first)"
    )
    ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_along_axis(d: Diagnosis, path: Path) -> Path:
    """Normalised residual energy over the carriage position, per direction, before and after
    the accepted effects, with the spans where it is concentrated."""
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    sigma_x, sigma_i = d.floors.sigma_position_m, d.floors.sigma_current
    for ax, (res, label, spans) in zip(
        axes,
        (
            (joined([d.train_before, d.holdout_before]), "before", d.where.along_axis),
            (
                d.holdout_after,
                "after the accepted effects (held out)",
                d.remaining_where.along_axis,
            ),
        ),
        strict=True,
    ):
        energy = res.normalised_energy(sigma_x, sigma_i)
        for sign, colour in ((1, "tab:blue"), (-1, "tab:orange")):
            inside = res.direction == sign
            ax.plot(
                res.x[inside] * 1e3,
                energy[inside],
                ".",
                ms=1.5,
                color=colour,
                label=f"moving {'+' if sign > 0 else '-'}",
            )
        for span in spans:
            ax.axvspan(span.from_mm, span.to_mm, color="red", alpha=0.2)
        if np.any(energy > 0):
            ax.set_yscale("log")
        ax.set_ylabel(f"normalised energy ({label})")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[1].set_xlabel("carriage position [mm]  (red: spans where the residual is concentrated)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


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


def write_report(d: Diagnosis, out: Path, extra: dict[str, Any] | None = None) -> dict[str, str]:
    """Write diagnosis.json (the summary and ``extra``), report.md, report.html and the figures
    into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    summary = {**d.summary(), **(extra or {})}
    (out / "diagnosis.json").write_text(json.dumps(summary, indent=2) + "\n")
    plot_residuals(d, out / "residuals.png")
    plot_regimes(d, out / "regimes.png")
    plot_along_axis(d, out / "along_axis.png")
    plot_spectra(d, out / "spectra.png")
    plot_ranking(d, out / "ranking.png")
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
    markdown += ["## Figures", ""] + [f"![{name}]({name})" for name in FIGURES] + [""]
    page += ["<h2>Figures</h2>"] + [f"<p><img src='{name}' alt='{name}'></p>" for name in FIGURES]
    page.append("</body></html>")
    (out / "report.md").write_text("\n".join(markdown))
    (out / "report.html").write_text("\n".join(page) + "\n")
    return {
        "json": str(out / "diagnosis.json"),
        "markdown": str(out / "report.md"),
        "html": str(out / "report.html"),
    }
