"""CUSUM tests: the design of the threshold against simulated run lengths, the baseline spread's
confidence bound, the change point and the rate of a ramp."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.runtime.sequential import (
    ALLOWANCE,
    Cusum,
    baseline_spread,
    siegmund_arl,
    threshold_for,
)


def test_the_threshold_inverts_siegmunds_average_run_length() -> None:
    for arl in (50.0, 1e3, 1e5):
        assert math.isclose(siegmund_arl(threshold_for(arl)), arl, rel_tol=1e-6)
    # The textbook value: k = 0.5, h = 4 gives an in-control ARL of about 336 windows.
    assert 300 < siegmund_arl(4.0, 0.5) < 400


def test_simulated_run_lengths_of_normal_increments_match_the_design() -> None:
    rng = np.random.default_rng(0)
    h = threshold_for(100.0)
    runs, length = 400, 3000
    z = rng.standard_normal((runs, length))
    s = np.zeros(runs)
    stopped = np.full(runs, length)
    for t in range(length):
        s = np.maximum(0.0, s + z[:, t] - ALLOWANCE)
        newly = (s > h) & (stopped == length)
        stopped[newly] = t + 1
    assert 80 < np.mean(stopped) < 125  # Siegmund's approximation within the sampling spread


def test_the_baseline_spread_is_raised_to_its_upper_confidence_bound() -> None:
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    from scipy.stats import chi2

    factor = math.sqrt(7 / chi2.ppf(0.1, 7))  # one-sided 90 % with 7 degrees of freedom
    assert math.isclose(baseline_spread(values), np.std(values, ddof=1) * factor)
    assert baseline_spread(np.ones(5), floor=0.25) == 0.25
    with pytest.raises(ValueError, match="at least 3"):
        baseline_spread(np.ones(2))


def test_a_ramp_is_found_with_its_start_and_rate_and_alarms_once() -> None:
    test = Cusum("friction", mean=0.0, spread=1.0, threshold=threshold_for(1e4))
    rng = np.random.default_rng(1)
    alarms = []
    for window in range(40):
        drift = 0.8 * (window - 19) if window >= 20 else 0.0
        if test.update(window, drift + 0.3 * rng.standard_normal()):
            alarms.append(window)
    assert len(alarms) == 1 and 20 <= alarms[0] <= 30
    assert test.direction == 1 and 18 <= test.since <= 21
    assert test.rate() == pytest.approx(0.8, rel=0.25)


def test_a_fall_is_found_by_a_two_sided_test_only() -> None:
    both = Cusum("a", 0.0, 1.0, 5.0)
    rise_only = Cusum("b", 0.0, 1.0, 5.0, two_sided=False)
    for window in range(10):
        both.update(window, -3.0)
        rise_only.update(window, -3.0)
    assert both.crossed is not None and both.direction == -1
    assert rise_only.crossed is None
