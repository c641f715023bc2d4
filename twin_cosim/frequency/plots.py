"""Bode and Nyquist figures of measured and linearised responses (PNG, matplotlib's Agg)."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from twin_cosim.frequency.margins import Margins  # noqa: E402
from twin_cosim.frequency.response import FrequencyResponse  # noqa: E402


def plot_bode(
    responses: Mapping[str, FrequencyResponse],
    title: str,
    path: Path,
    margins: Margins | None = None,
    coherence_floor: float | None = None,
) -> Path:
    """Magnitude, phase and (where measured) coherence against frequency; returns ``path``.

    ``responses`` by label: measured ones (with a coherence) drawn as points, computed ones as
    lines; ``margins`` marks the crossover and phase margin; ``coherence_floor`` draws that
    level.
    """
    measured = any(r.coherence is not None for r in responses.values())
    rows, ratios = (3, [3, 2, 1]) if measured else (2, [3, 2])
    fig, axes = plt.subplots(rows, 1, figsize=(9, 3 * rows), sharex=True, height_ratios=ratios)
    phases = _phases(list(responses.values()))
    for i, (label, r) in enumerate(responses.items()):
        style = {"marker": ".", "ms": 3, "lw": 0.6} if r.coherence is not None else {"lw": 1.2}
        axes[0].semilogx(r.frequency_hz, r.magnitude_db, label=label, **style)
        axes[1].semilogx(r.frequency_hz, phases[i], **style)
        if r.coherence is not None:
            axes[2].semilogx(r.frequency_hz, r.coherence, label=label, **style)
    first = next(iter(responses.values()))
    unit = "" if first.unit == "1" else f" re 1 {first.unit}"
    axes[0].set_ylabel(f"magnitude [dB{unit}]")
    axes[1].set_ylabel("phase [deg]")
    axes[-1].set_xlabel("frequency [Hz]")
    if measured:
        axes[2].set_ylabel("coherence")
        axes[2].set_ylim(-0.05, 1.05)
    if measured and coherence_floor is not None:
        axes[2].axhline(coherence_floor, color="tab:red", lw=0.8, ls="--", label="floor")
    if margins is not None and margins.crossover_hz is not None:
        for ax in axes[:2]:
            ax.axvline(margins.crossover_hz, color="grey", lw=0.8, ls=":")
        axes[0].axhline(0.0, color="grey", lw=0.8, ls=":")
        axes[1].set_title(
            f"phase margin {margins.phase_margin_deg:.1f} deg at {margins.crossover_hz:.1f} Hz"
            + (
                ""
                if margins.gain_margin_db is None
                else f", gain margin {margins.gain_margin_db:.1f} dB at "
                f"{margins.phase_crossover_hz:.0f} Hz"
            ),
            fontsize=9,
        )
    axes[0].set_title(_wrapped(title), fontsize=9)
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _wrapped(title: str, width: int = 110) -> str:
    """A title's lines wrapped at ``width`` characters (a command line can be long)."""
    return "\n".join(textwrap.fill(line, width) for line in title.splitlines())


def _phases(responses: list[FrequencyResponse]) -> list[np.ndarray]:
    """Unwrapped phases (deg); the first shifted by whole turns to lie nearest the second's
    (a measurement whose low lines are noise can unwrap a turn away)."""
    phases = [np.degrees(np.unwrap(np.angle(r.response))) for r in responses]
    if len(phases) > 1 and len(phases[0]) == len(phases[1]):
        turns = np.round(np.median(phases[1] - phases[0]) / 360.0)
        phases[0] = phases[0] + 360.0 * turns
    return phases


def plot_nyquist(responses: Mapping[str, FrequencyResponse], title: str, path: Path) -> Path:
    """The Nyquist plot of open loops near -1 (the unit circle and -1 marked); returns ``path``."""
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for i, (label, r) in enumerate(responses.items()):
        style = {"marker": ".", "ms": 3, "lw": 0.6} if i == 0 else {"lw": 1.2}
        ax.plot(r.response.real, r.response.imag, label=label, **style)
    circle = np.exp(1j * np.linspace(0, 2 * np.pi, 200))
    ax.plot(circle.real, circle.imag, color="grey", lw=0.6, ls=":")
    ax.plot([-1], [0], "x", color="tab:red", ms=9, label="-1")
    ax.set_xlim(-3, 1.5)
    ax.set_ylim(-3, 1.5)
    ax.set_aspect("equal")
    ax.set_xlabel("real")
    ax.set_ylabel("imaginary")
    ax.set_title(_wrapped(title, 80), fontsize=8)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
