"""The polar plot of a circular test, as ballbar software draws it: the radial deviation from
the nominal circle magnified around it, CW and CCW overlaid, reversal spikes marked."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from twin_cosim.contour.iso230 import CircleResult  # noqa: E402

COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple")
RING_SHARE = 0.4  # the deviation band drawn as this share of the plot's radius
MARKED_SHARE = 0.1  # spikes of at least this share of the drawn band (and 0.5 um) are marked


def plot_circle(
    results: Sequence[tuple[str, CircleResult]],
    radius_mm: float,
    hysteresis_um: float | None,
    command: str,
    path: Path,
) -> Path:
    """Write the polar plot of one circle's directions; returns ``path``.

    Parameters
    ----------
    results
        (label, evaluation) of each path drawn: CW and CCW, or a measured test and the twin.
    radius_mm
        Nominal radius, mm.
    hysteresis_um
        H (um) when both directions ran, else None.
    command
        The command that made the figure (written under the title).
    path
        PNG file to write.
    """
    deviations = np.concatenate([r.deviation_um for _, r in results])
    low, high = float(deviations.min()), float(deviations.max())
    margin = max(0.15 * (high - low), 0.5)
    low, high = min(low - margin, 0.0), max(high + margin, 0.0)
    fig = plt.figure(figsize=(8.5, 9))
    ax = fig.add_subplot(projection="polar")
    ax.set_rorigin(low - (high - low) * (1 - RING_SHARE) / RING_SHARE)
    ax.set_rlim(low, high)
    circle = np.linspace(0.0, 2 * math.pi, 721)
    ax.plot(circle, np.zeros_like(circle), color="0.3", ls="--", lw=0.8, label="nominal circle")
    for (label, result), colour in zip(results, COLOURS, strict=False):
        order = np.argsort(result.angle_deg)
        theta = np.radians(result.angle_deg[order])
        speed = result.speed_mm_min
        ellipse = result.mismatch
        lagging = ellipse["lagging_axis"]
        ax.plot(
            theta,
            result.deviation_um[order],
            color=colour,
            lw=1.2,
            label=f"{label} at {speed:.0f} mm/min: G {result.G_um:.2f} um, "
            f"F {result.F_um:.2f} um; ellipse {ellipse['size_um']:.2f} um at "
            f"{ellipse['major_axis_deg']:.0f} deg" + (f" ({lagging} lags)" if lagging else ""),
        )
        shown = max(0.5, MARKED_SHARE * (high - low))
        for spike in (s for s in result.spikes if abs(s.height_um) >= shown):
            at = np.interp(spike.peak_deg, result.angle_deg[order], result.deviation_um[order])
            ax.plot(math.radians(spike.peak_deg), at, marker="v", color=colour, ms=7)
            ax.annotate(
                f"{spike.axis} {spike.height_um:+.1f} um\n{spike.width_ms:.0f} ms",
                (math.radians(spike.peak_deg), at),
                textcoords="offset points",
                xytext=(6, 6),
                fontsize=7,
                color=colour,
            )
    ax.set_rlabel_position(67.5)
    ax.set_title(
        f"circular test, radius {radius_mm:g} mm: radial deviation [um] from the nominal circle"
        + (f", H {hysteresis_um:.2f} um" if hysteresis_um is not None else "")
        + f"\n{command}",
        fontsize=9,
    )
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
