"""The figure of a part program's run: the path, its contour error, each axis' error."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from twin_cosim.contour.machine_run import MachineRecord  # noqa: E402
from twin_cosim.metrics import UM_PER_M  # noqa: E402

MAGNIFICATION_SHARE = 0.05  # the drawn contour error at its largest: this share of the part's size


def plot_contour(record: MachineRecord, title: str, command: str, path: Path) -> Path:
    """Programmed and actual path (the deviation magnified), contour error and axis errors.

    Parameters
    ----------
    record
        The machine run.
    title
        Figure title.
    command
        The command that made the figure (written under the title).
    path
        PNG file to write; returned.
    """
    contour = record.contour
    t = contour["t"].to_numpy()
    ref = contour[["x_ref", "y_ref"]].to_numpy()
    actual = contour[["x", "y"]].to_numpy()
    error = contour["contour_error"].to_numpy()
    size = float(np.ptp(ref, axis=0).max()) or 1e-3
    gain = MAGNIFICATION_SHARE * size / max(float(error.max()), 1e-12)
    fig = plt.figure(figsize=(11, 8.5))
    grid = fig.add_gridspec(2, 2, width_ratios=(1, 1.3))
    ax = fig.add_subplot(grid[:, 0])
    ax.plot(ref[:, 0] * 1e3, ref[:, 1] * 1e3, color="k", lw=1, label="programmed")
    drawn = ref + gain * (actual - ref)
    ax.plot(
        drawn[:, 0] * 1e3,
        drawn[:, 1] * 1e3,
        color="tab:red",
        lw=1,
        label=f"actual, deviation x{gain:.3g}",
    )
    ax.set_aspect("equal")
    ax.set_xlabel("X [mm]")
    ax.set_ylabel("Y [mm]")
    ax.legend(loc="best", fontsize=8)
    top = fig.add_subplot(grid[0, 1])
    top.plot(t, error * UM_PER_M, lw=0.8, color="tab:red")
    top.set_ylabel("contour error [um]")
    top.set_title(
        f"contour error max {error.max() * UM_PER_M:.2f} um, "
        f"RMS {np.sqrt(np.mean(error**2)) * UM_PER_M:.2f} um",
        fontsize=9,
    )
    bottom = fig.add_subplot(grid[1, 1], sharex=top)
    for name, frame in record.axes.items():
        bottom.plot(frame["t"], frame["error"] * UM_PER_M, lw=0.8, label=f"{name}: x_ref - x")
    bottom.set_ylabel("axis position error [um]")
    bottom.set_xlabel("t [s]")
    bottom.legend(fontsize=8)
    fig.suptitle(f"{title}\n{command}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
