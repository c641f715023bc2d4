"""The diagnosis figures: labels inside the picture, titles that say which residual is shown."""

from __future__ import annotations

import dataclasses
import types

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from twin_cosim.gap.data.regimes import CONSTANT_VELOCITY  # noqa: E402
from twin_cosim.gap.data.residuals import Residuals, joined  # noqa: E402
from twin_cosim.gap.floors.noise import Floors  # noqa: E402
from twin_cosim.gap.location import AxisSpan, Location  # noqa: E402
from twin_cosim.gap.report import figures  # noqa: E402
from twin_cosim.measured import position_label  # noqa: E402


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


def _diagnosis(compared: str = "current"):
    """What the along-axis and spectra figures read of a diagnosis (``compared``: the signal
    compared beside the position)."""
    where = Location({}, {}, [AxisSpan(0.0, 1.0, 1, 0.6, 40.0, at_stroke_end=True)], {})
    after = Location({}, {}, [AxisSpan(22.0, 23.0, -1, 0.4, 12.0)], {})
    return types.SimpleNamespace(
        floors=Floors(2e-8, 5e-3, "test", "test"),
        train_before=_residuals(1),
        holdout_before=_residuals(2),
        holdout_after=_residuals(3),
        where=where,
        remaining_where=after,
        context=types.SimpleNamespace(
            screw_angle=lambda angle: angle / 1.5,
            compared=compared,
            train_end=1.0,
            position_label=position_label(compared, 1e-3),  # 1 mm of load travel per rad
        ),
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


def test_spectra_of_an_open_loop_run_name_the_motor_speed_the_angle_and_their_units(
    tmp_path, saved_figure
):
    figures.plot_spectra(_diagnosis("motor_speed"), tmp_path / "spectra.png")
    axes = saved_figure["fig"].axes
    assert axes[1].get_title().startswith("motor speed residual")
    assert axes[1].get_ylabel() == "amplitude [rad/s]"
    assert axes[0].get_title().startswith("angle residual")
    assert axes[0].get_ylabel() == "amplitude [rad]"


def _candidate(name: str, z: float, share: float, failed: list[str]):
    gain = types.SimpleNamespace(
        evidence_z=z, critical_z=3.14, excess_share=share, fair_share=1 / 12
    )
    judgement = types.SimpleNamespace(gain=gain, failed=failed)
    return types.SimpleNamespace(name=name, judgement=judgement, passes=not failed)


def test_the_ranking_shows_both_tests_and_which_failed(tmp_path, saved_figure):
    """A hypothesis beyond the needed z that fails the fair share is not drawn like one that
    passes, and a negative evidence z is drawn negative, not as 0."""
    candidates = [
        _candidate("stribeck", 244.0, 0.62, []),
        _candidate("torque_ripple", 88.0, 0.02, ["fair share"]),
        _candidate("pitch_error", 25.0, 0.11, []),
        _candidate("backlash_change", -231.0, -0.4, ["reduction", "evidence", "fair share"]),
    ]
    first = types.SimpleNamespace(candidates=candidates, accepted=["stribeck"])
    figures.plot_ranking(types.SimpleNamespace(rounds=[first]), tmp_path / "ranking.png")
    fig = saved_figure["fig"]
    evidence, share = fig.axes
    z_bars, share_bars = evidence.patches, share.patches
    assert [round(b.get_width(), 1) for b in z_bars] == [244.0, 88.0, 25.0, -231.0]
    assert [round(b.get_width(), 1) for b in share_bars] == [62.0, 2.0, 11.0, -40.0]
    colours = [b.get_facecolor() for b in z_bars]
    assert colours[0] != colours[2] != colours[1]  # accepted, passes, fails
    assert colours[1] == colours[3]
    labels = [t.get_text() for t in evidence.get_yticklabels()]
    assert labels[1] == "torque ripple  (fails: fair share)"
    assert labels[2] == "pitch error"
    lines = [line.get_xdata()[0] for line in share.get_lines() if line.get_linestyle() == "--"]
    assert lines == pytest.approx([100 / 12])


def test_joined_runs_are_drawn_apart_and_a_rotor_s_gap_as_its_angle(tmp_path, saved_figure):
    """Two runs one after the other (the time runs back between them) are not tied by a line;
    an open-loop rotor's gap is its angle in rad (its load position over 1 mm per rad), not a
    position of 1e6 um; a carriage's gap of metres is drawn in mm."""
    d = _diagnosis("motor_speed")
    two = joined([_residuals(1), _residuals(2)])
    d.train_before = dataclasses.replace(two, position=two.position * 1e8)  # about 2 m RMS
    figures.plot_residuals(d, tmp_path / "residuals.png")
    position_axis, compared_axis = saved_figure["fig"].axes
    assert position_axis.get_ylabel() == "angle residual [rad]"
    assert compared_axis.get_ylabel() == "motor speed residual [rad/s]"
    angle = position_axis.get_lines()[0].get_ydata()
    np.testing.assert_allclose(angle[np.isfinite(angle)], d.train_before.position / 1e-3)
    t = position_axis.get_lines()[0].get_xdata()
    assert len(t) == len(two.t) + 1 and np.isnan(t[len(_residuals(1).t)])
    assert np.all(np.diff(t[np.isfinite(t)][: len(_residuals(1).t)]) > 0)
    carriage = _diagnosis("current")
    carriage.train_before = d.train_before
    figures.plot_residuals(carriage, tmp_path / "residuals.png")
    assert saved_figure["fig"].axes[0].get_ylabel() == "position residual [mm]"
