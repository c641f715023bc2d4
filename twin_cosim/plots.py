"""Figures a servo engineer looks at, written as PNG files.

Drawn on matplotlib :class:`~matplotlib.figure.Figure` objects without pyplot (a third of
matplotlib's import time, and no global figure state): ``savefig`` renders with the Agg backend.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from twin_cosim.metrics import UM_PER_M, Metrics

if TYPE_CHECKING:
    from twin_cosim.open_loop import OpenLoopComparison
    from twin_cosim.run_record import RunRecord

# The close-up on a peak: the event starts tens of ms before it and settles within 0.2 s after
CLOSE_UP_BEFORE_S = 0.06
CLOSE_UP_AFTER_S = 0.24
# The running mean drawn over an open-loop run's drive (a measured torque is noisy sample to
# sample), s
DRIVE_MEAN_S = 0.1


def stacked_axes(rows: int, size: tuple[float, float], height_ratios: list[float]):  # type: ignore[no-untyped-def]
    """A figure of ``rows`` axes one above the other sharing the frequency or time axis, and
    its axes."""
    fig = Figure(figsize=size)
    axes = fig.subplots(rows, 1, sharex=True, height_ratios=height_ratios, squeeze=False)
    return fig, list(axes[:, 0])


def save_figure(fig: Figure, axes, path: Path) -> Path:  # type: ignore[no-untyped-def]
    """Grid every axis, lay the figure out and write it as a PNG (110 dpi); returns ``path``."""
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


def warm_up() -> None:
    """Draw a small figure with text into memory: what the first figure of a process loads
    (the PNG backend, the fonts) is loaded now, e.g. by a process that waits for its data."""
    import io

    fig = Figure(figsize=(1, 1))
    fig.subplots().set_title("t [s]")
    fig.savefig(io.BytesIO(), format="png")


def _close_up(
    ax, records: Mapping[str, RunRecord], centre: float, column: str, scale: float
) -> None:
    for label, record in records.items():
        offset = record["t"] - centre
        near = (offset >= -CLOSE_UP_BEFORE_S) & (offset <= CLOSE_UP_AFTER_S)
        ax.plot(record["t"][near], record[column][near] * scale, label=label, lw=1)


def plot_run(record: RunRecord, metrics: Metrics, title: str, path: Path) -> Path:
    """One run: reference and speed; position error with a close-up on its peak; current.

    Like the paper's Figs. 3, 4, 6 and 7. Returns the written path.
    """
    fig = Figure(figsize=(10, 11))
    axes = fig.subplots(4, 1)
    t = record["t"]
    ax = axes[0]
    ax.plot(t, record["x_ref"] * 1e3, color="k", lw=1)
    ax.set_ylabel("reference [mm]")
    speed_ax = ax.twinx()
    speed_ax.plot(t, record["v_ref"] * 1e3, color="tab:orange", lw=1)
    speed_ax.set_ylabel("reference speed [mm/s]", color="tab:orange")
    ax.set_title(title)
    axes[1].plot(t, record["error"] * UM_PER_M, lw=0.8)
    axes[1].axvline(metrics.t_E_pk, color="r", ls=":", lw=1)
    axes[1].set_ylabel("position error [um]")
    axes[1].set_title(
        f"E_pk {metrics.E_pk_um:.2f} um at {metrics.t_E_pk:.3f} s, RMS {metrics.rms_um:.2f} um, "
        f"mean |e| {metrics.mean_abs_um:.2f} um, ITAE {metrics.ITAE:.2f} um.s^2"
    )
    _close_up(axes[2], {"error": record}, metrics.t_E_pk, "error", UM_PER_M)
    axes[2].set_ylabel("error, close-up [um]")
    current_ax = axes[2].twinx()
    _close_up(current_ax, {"current": record}, metrics.t_E_pk, "current", 1.0)
    current_ax.lines[0].set_color("tab:green")
    current_ax.set_ylabel("current [A]", color="tab:green")
    axes[3].plot(t, record["current"], color="tab:green", lw=0.8)
    axes[3].set_ylabel("current command [A]")
    axes[3].set_title(f"IAU {metrics.IAU:.3f} A.s, max |i| {metrics.max_current_A:.2f} A")
    for ax in axes:
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
    # fixed margins that hold these labels: tight_layout would draw the figure once more
    fig.subplots_adjust(left=0.08, right=0.92, top=0.96, bottom=0.05, hspace=0.45)
    fig.savefig(path, dpi=110)
    return path


def plot_open_loop(
    record: RunRecord, comparison: OpenLoopComparison, title: str, path: Path
) -> Path:
    """An open-loop replay: measured and twin motor speed, their difference, the current
    command that drove the plant. Returns the written path.

    ``record`` holds the twin's columns and the measured ones beside them
    (:func:`twin_cosim.open_loop.with_measured`).
    """
    fig = Figure(figsize=(10, 9))
    axes = fig.subplots(3, 1, sharex=True)
    t = record["t"]
    c = comparison
    axes[0].plot(t, record["measured_motor_speed"], color="k", lw=0.6, label="measured")
    axes[0].plot(t, record["motor_speed"], color="tab:blue", lw=1.2, label="twin")
    steady = "\n".join(
        f"at {level.commanded:.3g} {c.commanded_unit}: "
        f"steady {level.measured_rad_s:.0f} rad/s measured, "
        f"{level.twin_rad_s:.0f} twin ({level.relative_error_pct:+.1f} %)"
        for level in c.levels
    )
    forwards = not c.levels or c.levels[0].commanded >= 0
    axes[0].text(
        0.01,
        0.96 if forwards else 0.04,
        steady,
        transform=axes[0].transAxes,
        va="top" if forwards else "bottom",
        fontsize=8,
        bbox={"facecolor": "white", "edgecolor": "0.8", "alpha": 0.9},
    )
    axes[0].set_ylabel("motor speed [rad/s]")
    axes[0].legend(loc="lower right" if forwards else "upper right")
    axes[0].set_title(title)
    axes[1].plot(t, record["measured_motor_speed"] - record["motor_speed"], lw=0.6)
    axes[1].set_ylabel("measured - twin [rad/s]")
    axes[1].set_title(
        f"velocity gap RMS {c.speed_rms_gap_rad_s:.3g} rad/s "
        f"({c.speed_relative_error_pct:.3g} % of the measured speed's norm)"
    )
    current = record["current"]
    axes[2].plot(t, current, color="tab:green", lw=0.8, label="each sample")
    window = max(int(round(DRIVE_MEAN_S / float(np.median(np.diff(t))))), 1)
    padded = np.pad(current, (window // 2, window - 1 - window // 2), mode="edge")
    axes[2].plot(
        t,
        np.convolve(padded, np.full(window, 1.0 / window), mode="valid"),
        color="k",
        lw=1.0,
        label=f"mean over {DRIVE_MEAN_S:g} s",
    )
    axes[2].legend(loc="lower right" if forwards else "upper right", fontsize=8)
    low, high = np.percentile(current, [0.5, 99.5])  # a measured drive's rare spikes off scale
    margin = 0.15 * max(high - low, abs(high), abs(low), 1e-9)
    axes[2].set_ylim(min(low, 0.0) - margin, max(high, 0.0) + margin)
    axes[2].set_ylabel("current command [A]")
    axes[2].set_title(f"the drive: {c.drive} as the plant's current command")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[2].set_xlabel("t [s]")
    fig.subplots_adjust(left=0.09, right=0.97, top=0.95, bottom=0.06, hspace=0.35)
    fig.savefig(path, dpi=110)
    return path


def plot_error_comparison(
    records: Mapping[str, RunRecord], centre: float, title: str, path: Path
) -> Path:
    """Position errors of several parameter sets, whole run and close-up (paper Figs. 6-7, 11)."""
    fig = Figure(figsize=(10, 9))
    axes = fig.subplots(3, 1)
    for label, record in records.items():
        axes[0].plot(record["t"], record["error"] * UM_PER_M, label=label, lw=0.8)
    axes[0].set_title(title)
    axes[0].set_ylabel("position error [um]")
    _close_up(axes[1], records, centre, "error", UM_PER_M)
    axes[1].set_ylabel("error, close-up [um]")
    _close_up(axes[2], records, centre, "current", 1.0)
    axes[2].set_ylabel("current, close-up [A]")
    for ax in axes:
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)  # beside the data
    # fixed margins that hold the legends beside: tight_layout would draw the figure once more
    fig.subplots_adjust(left=0.08, right=0.78, top=0.96, bottom=0.06, hspace=0.35)
    fig.savefig(path, dpi=110)
    return path
