"""Amplitude spectra in Hz and orders; the position-periodic versus temporal verdict."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.spectra import (
    Peak,
    dominant_peak,
    frequency_spectrum,
    order_spectrum,
    periodicity,
)

DT = 250e-6  # s
A = 1e-6  # m


@pytest.mark.parametrize(("dt", "frequency"), [(DT, 123.25), (DT, 40.0), (1e-3, 7.3)])
def test_sine_amplitude_recovered(dt, frequency):
    t = np.arange(round(2.0 / dt)) * dt  # 2 s: bins 0.5 Hz, 123.25 Hz lies half a bin off
    residual = 3e-6 + A * np.sin(2 * np.pi * frequency * t + 0.4)
    f, amplitude = frequency_spectrum(residual, dt)
    assert f[1] - f[0] <= 0.5 / 4
    assert amplitude[0] < 0.05 * A  # the 3 um mean is removed
    peak = dominant_peak(f, amplitude)
    assert peak.amplitude == pytest.approx(A, rel=0.05)
    assert peak.location == pytest.approx(frequency, abs=0.05)
    assert amplitude.max() == pytest.approx(A, rel=0.05)


def speed_levels() -> tuple[np.ndarray, np.ndarray, list[list[tuple[int, int]]]]:
    """Angle (rad) at 5 and 8 rev/s, each level forwards and backwards, with the segments."""
    knots = [  # (time s, speed rev/s); cruises of 2 s joined by 0.5 s ramps
        (0.0, 5.0), (2.0, 5.0), (2.5, -5.0), (4.5, -5.0),
        (5.0, 8.0), (7.0, 8.0), (7.5, -8.0), (9.5, -8.0),
    ]  # fmt: skip
    t = np.arange(round(9.5 / DT)) * DT
    knot_t, knot_speed = np.array(knots).T
    speed = 2 * np.pi * np.interp(t, knot_t, knot_speed)
    angle = np.concatenate(([0.0], np.cumsum((speed[1:] + speed[:-1]) / 2) * DT))
    cruise = [(knot_t[k], knot_t[k + 1]) for k in (0, 2, 4, 6)]
    index = [(round(a / DT) + 1, round(b / DT)) for a, b in cruise]
    return t, angle, [index[:2], index[2:]]


def test_order_spectrum_of_a_position_periodic_residual():
    t, angle, groups = speed_levels()
    residual = A * np.sin(3 * angle + 1.0) + 1e-7 * t  # a drift is removed with the trend
    order, amplitude = order_spectrum(residual, angle, groups[0] + groups[1])
    assert order[-1] == 32.0  # capped at half of 64 samples per revolution
    peak = dominant_peak(order, amplitude)
    assert peak.location == pytest.approx(3.0, abs=0.01)
    assert peak.amplitude == pytest.approx(A, rel=0.05)


def test_reversed_angle_gives_the_same_order_spectrum():
    t, angle, groups = speed_levels()
    residual = A * np.sin(3 * angle)
    backward = groups[0][1:]  # the -5 rev/s cruise: the angle decreases
    assert np.all(np.diff(angle[slice(*backward[0])]) < 0)
    order, amplitude = order_spectrum(residual, angle, backward)
    peak = dominant_peak(order, amplitude)
    assert peak.location == pytest.approx(3.0, abs=0.01)
    assert peak.amplitude == pytest.approx(A, rel=0.05)
    order_neg, amplitude_neg = order_spectrum(residual, -angle, backward)
    np.testing.assert_allclose(order_neg, order)
    np.testing.assert_allclose(amplitude_neg, amplitude, atol=1e-3 * A)


def test_short_or_stalled_segments_give_an_empty_spectrum():
    _, angle, groups = speed_levels()
    order, amplitude = order_spectrum(np.zeros_like(angle), angle, [(0, 200)])  # 0.25 rev
    assert order.size == 0 and amplitude.size == 0
    assert dominant_peak(order, amplitude) is None
    stalled = angle.copy()
    stalled[1000:1100] = stalled[1000]
    order, _ = order_spectrum(np.zeros_like(angle), stalled, groups[0][:1])
    assert order.size == 0


def test_position_periodic_verdict():
    rng = np.random.default_rng(1)
    t, angle, groups = speed_levels()
    residual = A * np.sin(3 * angle + 0.3) + 0.2 * A * rng.standard_normal(t.size)
    result = periodicity(residual, angle, DT, groups)
    assert result["verdict"] == "position-periodic", result["reason"]
    for group, hz in zip(result["groups"], (15.0, 24.0), strict=True):
        assert group["order"].location == pytest.approx(3.0, rel=0.01)
        assert group["frequency_hz"].location == pytest.approx(hz, rel=0.01)
        assert group["order"].ratio >= 5.0
    assert "order 3" in result["reason"]


def test_temporal_verdict():
    rng = np.random.default_rng(2)
    t, angle, groups = speed_levels()
    residual = A * np.sin(2 * np.pi * 37.0 * t) + 0.2 * A * rng.standard_normal(t.size)
    result = periodicity(residual, angle, DT, groups)
    assert result["verdict"] == "temporal", result["reason"]
    for group, order in zip(result["groups"], (37 / 5, 37 / 8), strict=True):
        assert group["frequency_hz"].location == pytest.approx(37.0, rel=0.01)
        assert group["order"].location == pytest.approx(order, rel=0.01)
    assert "37 Hz" in result["reason"]


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_white_noise_is_inconclusive(seed):
    rng = np.random.default_rng(seed)
    t, angle, groups = speed_levels()
    result = periodicity(A * rng.standard_normal(t.size), angle, DT, groups)
    assert result["verdict"] == "inconclusive"
    assert "no significant" in result["reason"]


def test_inconclusive_with_one_group_or_equal_speeds():
    t, angle, groups = speed_levels()
    residual = A * np.sin(3 * angle)
    assert periodicity(residual, angle, DT, groups[:1])["verdict"] == "inconclusive"
    same_speed = [groups[0][:1], groups[0][1:]]  # +5 and -5 rev/s
    result = periodicity(residual, angle, DT, same_speed)
    assert result["verdict"] == "inconclusive"
    assert "too close" in result["reason"]


def test_dominant_peak_ignores_dc_and_needs_a_ratio():
    x = np.arange(10.0)
    assert dominant_peak(x, np.array([9.0, 1, 1, 1, 4, 1, 1, 1, 1, 1])) is None
    peak = dominant_peak(x, np.array([9.0, 1, 1, 1, 6, 1, 1, 1, 1, 1]))
    assert peak == Peak(location=4.0, amplitude=6.0, ratio=6.0)
    assert dominant_peak(x, np.zeros(10)) is None
