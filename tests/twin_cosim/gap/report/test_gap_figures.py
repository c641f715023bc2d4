"""The diagnosis figures: labels inside the picture, titles that say which residual is shown."""

from __future__ import annotations

import types

import matplotlib
import numpy as np

matplotlib.use("Agg")
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from twin_cosim.gap.data.regimes import CONSTANT_VELOCITY  # noqa: E402
from twin_cosim.gap.data.residuals import Residuals  # noqa: E402
from twin_cosim.gap.floors.noise import Floors  # noqa: E402
from twin_cosim.gap.location import AxisSpan, Location  # noqa: E402
from twin_cosim.gap.report import figures  # noqa: E402


def _residuals(seed: int) -> Residuals:
    rng = np.random.default_rng(seed)
    x = np.concatenate([np.linspace(0.0, 0.04, 4000), np.linspace(0.04, 0.0, 4000)])
    n = len(x)
    direction = np.concatenate([np.ones(4000), -np.ones(4000)])
    return Residuals(
        np.arange(n) * 250e-6,
        rng.normal(0, 2e-8, n),
        rng.normal(0, 5e-3, n),
        np.full(n, CONSTANT_VELOCITY),
        x / 0.004 * 2 * np.pi,
        x,
        direction,
    )


def _diagnosis():
    """What the along-axis and spectra figures read of a diagnosis."""
    where = Location({}, {}, [AxisSpan(0.0, 1.0, 1, 0.6, 40.0, at_stroke_end=True)], {})
    after = Location({}, {}, [AxisSpan(22.0, 23.0, -1, 0.4, 12.0)], {})
    return types.SimpleNamespace(
        floors=Floors(2e-8, 5e-3, "test", "test"),
        train_before=_residuals(1),
        holdout_before=_residuals(2),
        holdout_after=_residuals(3),
        where=where,
        remaining_where=after,
        context=types.SimpleNamespace(screw_angle=lambda angle: angle / 1.5),
    )


def test_along_axis_labels_fit_and_name_before_and_after(tmp_path, saved_figure):
    saved = saved_figure
    figures.plot_along_axis(_diagnosis(), tmp_path / "along_axis.png")
    fig = saved["fig"]
    renderer = FigureCanvasAgg(fig).get_renderer()  # the figure was closed after saving
    width, height = fig.bbox.width, fig.bbox.height
    axes = [ax for ax in fig.axes if ax.get_ylabel()]
    assert len(axes) == 2
    for ax in axes:
        box = ax.yaxis.label.get_window_extent(renderer)
        assert box.x0 >= 0 and box.y0 >= 0 and box.y1 <= height, ax.get_ylabel()
    lower, upper = (ax.yaxis.label.get_window_extent(renderer) for ax in axes)
    assert not lower.overlaps(upper)
    titles = [ax.get_title() for ax in axes]
    assert titles[0].startswith("before the accepted effects")
    assert titles[1].startswith("after the accepted effects")
    for ax in axes:
        legend = ax.get_legend().get_window_extent(renderer)
        assert legend.x1 <= width and legend.x0 >= ax.get_window_extent(renderer).x1
    legend_texts = [t.get_text() for ax in axes for t in ax.get_legend().get_texts()]
    assert "span where the axis starts, stops or reverses" in legend_texts
    assert "span along the travel" in legend_texts


def test_spectra_say_which_residual_they_show(tmp_path, saved_figure):
    saved = saved_figure
    figures.plot_spectra(_diagnosis(), tmp_path / "spectra.png")
    fig = saved["fig"]
    assert "training data, before the accepted effects" in fig._suptitle.get_text()
    titles = [ax.get_title() for ax in fig.axes]
    assert all(titles), titles
    renderer = FigureCanvasAgg(fig).get_renderer()
    for ax in fig.axes:
        box = ax.title.get_window_extent(renderer)
        assert box.x0 >= 0 and box.x1 <= fig.bbox.width, ax.get_title()
    assert titles[0].startswith("position residual") and titles[1].startswith("current residual")
