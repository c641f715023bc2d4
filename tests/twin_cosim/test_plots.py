"""Figures say what the tables say and show the event they zoom on."""

from __future__ import annotations

import dataclasses

import matplotlib.pyplot as plt
import numpy as np

from twin_cosim.controller_set import TABLE3, set_name
from twin_cosim.plots import _close_up
from twin_cosim.run_record import RunRecord


def test_run_png_names_the_set_as_the_tables_do():
    assert set_name(TABLE3["ft"]) == "FT (the scenario's set)"
    assert set_name(dataclasses.replace(TABLE3["ft"], Kp_pos=70.0)) == "the scenario's set"


def test_the_close_up_is_mostly_the_event_after_its_peak():
    """A reversal spike starts tens of ms before its peak and rings after it: the close-up
    shows little before the peak (it was half flat at +/-0.35 s)."""
    t = np.arange(0.0, 2.0, 0.00025)
    record = RunRecord.from_columns({"t": t, "error": np.exp(-(((t - 1.0) / 0.01) ** 2))})
    fig, ax = plt.subplots()
    _close_up(ax, {"FT": record}, 1.0, "error", 1.0)
    shown = ax.lines[0].get_xdata()
    plt.close(fig)
    assert shown.min() >= 1.0 - 0.1
    assert shown.max() - 1.0 > 2 * (1.0 - shown.min())
