"""The figures of a diagnosis report (PNG files, matplotlib's Agg backend).

Written after the report's pages and files (:mod:`twin_cosim.gap.report.pages`), unless
``twin diagnose --no-plots``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from twin_cosim.gap import spectra  # noqa: E402
from twin_cosim.gap.data import regimes as regime_model  # noqa: E402
from twin_cosim.gap.data.residuals import joined  # noqa: E402
from twin_cosim.gap.diagnosis import Diagnosis  # noqa: E402
from twin_cosim.gap.verdict import STROKE_END  # noqa: E402
from twin_cosim.measured import compared_label  # noqa: E402
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


def _saved(fig, path: Path) -> Path:
    """Lay the figure out, write it to ``path`` (PNG, 100 dpi) and free it."""
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _apart(t: np.ndarray, *values: np.ndarray) -> tuple[np.ndarray, ...]:
    """Times (s) and values with a gap (NaN) where the time runs back: runs joined one after
    the other are drawn apart, not tied by a line from one run's end to the next one's start."""
    cut = np.flatnonzero(np.diff(t) < 0) + 1
    return tuple(np.insert(np.asarray(v, dtype=float), cut, np.nan) for v in (t, *values))


def plot_residuals(d: Diagnosis, path: Path) -> Path:
    """Position and current residuals over time, regimes shaded, before and after the effects."""
    fig, axes = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    sets = (
        (d.train_before, "before (training)", "-"),
        (d.holdout_before, "before (held out)", "-"),
        (d.holdout_after, "after the accepted effects (held out)", "-"),
    )
    largest_m = max(float(np.max(np.abs(res.position), initial=0.0)) for res, _, _ in sets)
    x = d.context.position_label
    position_unit, per_m = x.figure_scale(largest_m)
    for res, label, style in sets:
        t, position, compared = _apart(res.t, res.position * per_m, res.current)
        axes[0].plot(t, position, style, lw=0.7, label=label)
        axes[1].plot(t, compared, style, lw=0.7, label=label)
    for ax in axes:
        _shade_regimes(ax, d.train_before.t, d.train_before.regimes)
        _shade_regimes(ax, d.holdout_before.t, d.holdout_before.regimes)
        ax.axvline(d.context.train_end, color="k", ls="--", lw=1)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[0].set_ylabel(f"{x.words} residual [{position_unit}]")
    words, unit = compared_label(d.context.compared)
    axes[1].set_ylabel(f"{words} residual [{unit}]")
    axes[1].set_xlabel(
        "t [s]  (shading: standstill grey, breakaway orange, acceleration blue, reversal red)"
    )
    return _saved(fig, path)


def plot_regimes(d: Diagnosis, path: Path) -> Path:
    """Share of residual energy against share of time per regime."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    names = list(regime_model.REGIMES)
    x = np.arange(len(names))
    titles = {
        "position": d.context.position_label.words,
        "current": compared_label(d.context.compared)[0],
    }
    for ax, signal in zip(axes, ("position", "current"), strict=True):
        shares = getattr(d.where, signal)
        ax.bar(x - 0.2, [shares[n]["time_share"] for n in names], 0.4, label="time share")
        ax.bar(
            x + 0.2, [shares[n]["energy_share"] for n in names], 0.4, label="residual energy share"
        )
        ax.set_xticks(x, [n.replace("_", "\n") for n in names], fontsize=8)
        ax.set_title(f"{titles[signal]} residual")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    return _saved(fig, path)


def plot_spectra(d: Diagnosis, path: Path) -> Path:
    """Amplitude spectra of the training residual before the accepted effects (measured minus
    the nominal twin): in Hz over the whole training data, and in orders of the motor and the
    screw angle over its constant-velocity stretches; position left, current right."""
    res = d.train_before
    dt = float(np.median(np.diff(res.t)))
    stretches = regime_model.segments(res.regimes, regime_model.REGIMES.index("constant_velocity"))
    fig, axes = plt.subplots(3, 2, figsize=(11, 9.5))
    compared, compared_unit = compared_label(d.context.compared)
    x = d.context.position_label
    position = (x.words, res.position * UM_PER_M * x.per_um, x.unit)
    for column, (signal, values, unit) in enumerate(
        (position, (compared, res.current, compared_unit))
    ):
        f, a = spectra.frequency_spectrum(values, dt)
        axes[0, column].loglog(f[1:], a[1:] + 1e-12, lw=0.7)
        axes[0, column].set_xlabel("frequency [Hz]")
        axes[0, column].set_title(f"{signal} residual, whole training data", fontsize=10)
        for row, (angle_name, angle) in enumerate(
            (("motor", res.motor_angle), ("screw", d.context.screw_angle(res.motor_angle))), start=1
        ):
            orders, amplitude = spectra.order_spectrum(values, angle, stretches)
            if len(orders):
                axes[row, column].semilogy(orders[1:], amplitude[1:] + 1e-12, lw=0.8)
            axes[row, column].set_xlabel(f"order of the {angle_name} angle [cycles/rev]")
            axes[row, column].set_title(
                f"{signal} residual, {angle_name} angle orders (constant velocity)", fontsize=10
            )
        for row in range(3):
            axes[row, column].set_ylabel(f"amplitude [{unit}]")
            axes[row, column].grid(alpha=0.3, which="both")
    fig.suptitle(
        "Residual spectra: training data, before the accepted effects (measured - nominal twin)"
    )
    return _saved(fig, path)


RANKING_COLOURS = {"accepted": "tab:green", "passes": "#a1d99b", "fails": "#bbbbbb"}


def plot_ranking(d: Diagnosis, path: Path) -> Path:
    """The first round's hypotheses (best training BIC first) against the two tests of the
    acceptance rule's gain: the evidence z beyond calibration and noise (left, the needed z
    dashed) and the share of the excess energy above the noise each removes (right, the fair
    share dashed), both against the linear calibration corrections; a bar's colour says whether
    it passed every test (and was accepted), each label the tests it failed
    (:attr:`~twin_cosim.gap.which.acceptance.Judgement.failed`: a bar past both lines can fail
    another, such as the gain with the corrections replayed)."""
    first = d.rounds[0]
    rows = first.candidates
    fig, (evidence, share) = plt.subplots(
        1, 2, figsize=(11, 1.2 + 0.38 * max(len(rows), 3)), sharey=True
    )
    if rows:
        y = np.arange(len(rows))
        kinds = [
            "accepted" if c.name in first.accepted else "passes" if c.passes else "fails"
            for c in rows
        ]
        colours = [RANKING_COLOURS[k] for k in kinds]
        gains = [c.judgement.gain for c in rows]
        evidence.barh(y, [g.evidence_z for g in gains], color=colours)
        evidence.axvline(gains[0].critical_z, color="r", ls="--", lw=1)
        evidence.set_xscale("symlog", linthresh=1.0)
        evidence.axvline(0.0, color="k", lw=0.6)
        share.barh(y, [100.0 * g.excess_share for g in gains], color=colours)
        share.axvline(100.0 * gains[0].fair_share, color="r", ls="--", lw=1)
        share.axvline(0.0, color="k", lw=0.6)
        share.set_xscale("symlog", linthresh=10.0)
        labels = [
            c.name.replace("_", " ")
            + (f"  (fails: {', '.join(c.judgement.failed)})" if k == "fails" else "")
            for c, k in zip(rows, kinds, strict=True)
        ]
        evidence.set_yticks(y, labels, fontsize=8)
        evidence.invert_yaxis()
        handles = [
            Patch(color=RANKING_COLOURS[k], label=label)
            for k, label in (
                ("accepted", "accepted"),
                ("passes", "passes every test, not accepted"),
                ("fails", "fails a test"),
            )
        ] + [plt.Line2D([], [], color="r", ls="--", lw=1, label="what the rule asks")]
        fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8, frameon=False)
    evidence.set_xlabel(
        "evidence z of the held-out improvement\nbeyond calibration error and noise"
    )
    share.set_xlabel("share of the held-out energy above the noise\nthat it removes [%]")
    for ax in (evidence, share):
        ax.grid(alpha=0.3, axis="x")
    fig.suptitle(
        "Round 1: each hypothesis fitted on the training data, judged on the held-out data "
        "(best training BIC first)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


SPAN_COLOURS = {False: "tab:red", True: "tab:purple"}  # by AxisSpan.at_stroke_end
SPAN_LABELS = {False: "along the travel", True: STROKE_END}


def plot_along_axis(d: Diagnosis, path: Path) -> Path:
    """Normalised residual energy over the carriage position, per direction, before and after
    the accepted effects, with the spans where it is concentrated (red along the travel,
    purple where the axis starts, stops or reverses)."""
    fig, axes = plt.subplots(2, 1, figsize=(11, 7), sharex=True)
    sigma_x, sigma_i = d.floors.sigma_position_m, d.floors.sigma_current
    label = d.context.position_label
    shown, per_m = label.figure_scale(
        max(
            float(np.max(np.abs(r.x), initial=0.0))
            for r in (d.train_before, d.holdout_before, d.holdout_after)
        )
    )
    panels = (
        (
            joined([d.train_before, d.holdout_before]),
            "before the accepted effects (training and held-out data)",
            d.where.along_axis,
        ),
        (
            d.holdout_after,
            "after the accepted effects (held-out data)",
            d.remaining_where.along_axis,
        ),
    )
    for ax, (res, title, spans) in zip(axes, panels, strict=True):
        energy = res.normalised_energy(sigma_x, sigma_i)
        for sign, colour in ((1, "tab:blue"), (-1, "tab:orange")):
            inside = res.direction == sign
            ax.plot(
                res.x[inside] * per_m,
                energy[inside],
                ".",
                ms=1.5,
                color=colour,
                label=f"moving {'+' if sign > 0 else '-'}",
            )
        for span in spans:
            ax.axvspan(
                span.from_mm * 1e-3 * per_m,
                span.to_mm * 1e-3 * per_m,
                color=SPAN_COLOURS[span.at_stroke_end],
                alpha=0.2,
            )
        ax.axhline(1.0, color="k", lw=0.8, ls="--", label="noise at the floors")
        handles = ax.get_legend_handles_labels()[0] + [
            Patch(color=colour, alpha=0.2, label=f"span {SPAN_LABELS[at_end]}")
            for at_end, colour in SPAN_COLOURS.items()
            if any(s.at_stroke_end == at_end for s in spans)
        ]
        if np.any(energy > 0):
            ax.set_yscale("log")
        ax.set_title(title, fontsize=10)
        ax.set_ylabel("normalised energy\n(1: noise at the floors)")
        ax.grid(alpha=0.3)
        ax.legend(
            handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, markerscale=4
        )
    axes[1].set_xlabel(f"{label.axis_words} [{shown}]")
    return _saved(fig, path)


def write_figures(d: Diagnosis, out: Path) -> None:
    """Write the report's figures (:data:`twin_cosim.gap.report.pages.FIGURES`) into ``out``."""
    plot_residuals(d, out / "residuals.png")
    plot_regimes(d, out / "regimes.png")
    plot_along_axis(d, out / "along_axis.png")
    plot_spectra(d, out / "spectra.png")
    plot_ranking(d, out / "ranking.png")
