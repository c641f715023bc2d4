"""ISO 230-4 figures on known paths: a perfect circle, an offset one, an ellipse, a bump."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from twin_cosim.contour.iso230 import evaluate_circle, hysteresis, least_squares_circle

R = 0.01


def _data(deviation=lambda a: 0.0 * a, centre=(0.0, 0.0), direction="ccw", n=7200):
    sign = 1.0 if direction == "ccw" else -1.0
    angle = math.radians(45) + sign * np.linspace(0, 2 * math.pi, n, endpoint=False)
    r = R + deviation(angle)
    t = np.arange(n) * 1e-3
    x = centre[0] + r * np.cos(angle)
    y = centre[1] + r * np.sin(angle)
    return pd.DataFrame({"t": t, "x": x, "y": y})


def test_a_perfect_circle_has_no_deviation_and_no_spikes():
    result = evaluate_circle(_data(), R, "ccw", 0.0167)
    assert result.G_um < 1e-6 and result.F_um < 1e-6
    assert all(abs(s.height_um) < 1e-6 for s in result.spikes)
    assert [s.axis for s in result.spikes] == ["X", "Y", "X", "Y"]


def test_least_squares_circle_finds_an_offset_centre_and_g_ignores_it():
    data = _data(centre=(3e-6, -2e-6))
    assert least_squares_circle(data["x"].to_numpy(), data["y"].to_numpy()) == pytest.approx(
        (3e-6, -2e-6, R), abs=1e-12
    )
    result = evaluate_circle(data, R, "ccw", 0.0167)
    assert result.G_um < 1e-6  # G is about the least-squares centre
    assert result.F_um == pytest.approx(math.hypot(3, 2), rel=1e-3)  # F about the nominal one


def test_an_ellipse_at_45_degrees_is_the_servo_mismatch_signature():
    ellipse = evaluate_circle(_data(lambda a: 4e-6 * np.cos(2 * (a - math.pi / 4))), R, "ccw", 0.02)
    assert ellipse.G_um == pytest.approx(8.0, rel=1e-3)
    assert ellipse.mismatch["size_um"] == pytest.approx(8.0, rel=1e-3)
    assert ellipse.mismatch["major_axis_deg"] == pytest.approx(45.0, abs=0.1)
    assert ellipse.mismatch["lagging_axis"] == "X"  # CCW, major axis at 45 degrees


def test_a_bump_after_a_transition_is_its_spike_with_height_and_width():
    def bump(angle):  # 5 um outward, 10 degrees wide, 3 degrees after 90 (CCW)
        offset = np.degrees(angle) % 360 - 93.0
        return 5e-6 * np.exp(-0.5 * (offset / 2.0) ** 2)

    result = evaluate_circle(_data(bump), R, "ccw", 0.0167)
    spike = result.spikes[1]
    assert spike.axis == "Y" and spike.angle_deg == 90.0
    assert spike.height_um == pytest.approx(5.0, rel=0.05)
    assert spike.peak_deg == pytest.approx(93.0, abs=0.1)
    fwhm_deg = 2 * math.sqrt(2 * math.log(2)) * 2.0  # one sample per 0.05 degree and 1 ms
    assert spike.width_ms == pytest.approx(fwhm_deg / 0.05, rel=0.05)
    assert abs(result.spikes[0].height_um) < 0.1 * spike.height_um


def test_hysteresis_is_the_largest_radial_difference_of_the_two_directions():
    ccw = evaluate_circle(_data(lambda a: 2e-6 + 0 * a), R, "ccw", 0.02)
    cw = evaluate_circle(_data(lambda a: 1e-6 * np.sin(a), direction="cw"), R, "cw", 0.02)
    assert hysteresis(ccw, cw) == pytest.approx(3.0, rel=1e-3)
