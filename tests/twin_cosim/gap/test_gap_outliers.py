"""Outliers of a measured run are repaired and reported, or the run is refused."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.outliers import screen_outliers
from twin_cosim.measured import MeasuredDataError, MeasuredRun


def run_with(current: np.ndarray) -> MeasuredRun:
    t = np.arange(len(current)) * 250e-6
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    return MeasuredRun.from_signals("run.csv", {"t": t, "x_ref": x, "x": x, "current": current})


def smooth_current(n: int = 20000) -> np.ndarray:
    rng = np.random.default_rng(0)
    t = np.arange(n) * 250e-6
    current = 0.5 * np.sign(np.cos(2 * np.pi * 0.5 * t)) + rng.normal(0, 5e-3, n)
    current[5000:5006] += 0.8  # a breakaway spike: several samples, within the range
    return current


def test_one_absurd_sample_is_replaced_and_reported():
    current = smooth_current()
    current[1234] = 1e12
    fixed, warnings = screen_outliers(run_with(current), 0.001)
    assert abs(fixed.current[1234]) < 1.0
    assert len(warnings) == 1 and "current[1234] = 1e+12" in warnings[0]
    assert fixed.current[5002] == current[5002]  # the breakaway spike stays


def test_a_clean_run_is_left_alone():
    run = run_with(smooth_current())
    fixed, warnings = screen_outliers(run, 0.001)
    assert warnings == [] and fixed is run


def test_a_run_full_of_glitches_is_refused():
    current = smooth_current()
    current[::500] = 1e6
    with pytest.raises(MeasuredDataError, match="run.csv: column 'current': 40 outliers"):
        screen_outliers(run_with(current), 0.001)
