"""Numbers for people: three significant digits and readable units."""

from __future__ import annotations

import math

import pytest

from twin_cosim.gap.numbers import names, number, parameters, percent, quantity


@pytest.mark.parametrize(
    ("value", "text"),
    [
        (0.20910341, "0.209"),
        (46.123, "46.1"),
        (1234.5, "1230"),
        (9.996, "10.0"),
        (0.0199, "0.0199"),
        (-0.0622, "-0.0622"),
        (2.644e-6, "2.64e-06"),
        (3.2e7, "3.20e+07"),
        (0.0, "0"),
        (None, "-"),
        (math.nan, "-"),
    ],
)
def test_three_significant_digits(value, text):
    assert number(value) == text


def test_lengths_and_times_take_a_readable_prefix():
    assert quantity(2.644e-6, "m") == "2.64 um"
    assert quantity(2.05e-8, "m") == "20.5 nm"
    assert quantity(0.1162, "m") == "116 mm"
    assert quantity(1.542e-4, "s") == "154 us"
    assert quantity(0.0052, "s") == "5.20 ms"
    assert quantity(0.2091, "N.m") == "0.209 N.m"
    assert quantity(2.0, "1") == "2"
    assert quantity(0.0, "m") == "0 m"


def test_shares_parameters_and_names():
    assert percent(0.2661) == "26.6 %"
    assert percent(1.0) == "100 %"
    units = {"stribeck_friction": "N.m", "stribeck_speed": "rad/s"}
    values = {"stribeck_friction": 0.19706049649074708, "stribeck_speed": 0.4025871809045728}
    assert parameters(values, units) == "stribeck_friction 0.197 N.m, stribeck_speed 0.403 rad/s"
    assert parameters({}, units) == "-"
    assert names(["stribeck", ["current_lag", "dead_time"]]) == "stribeck, {current_lag, dead_time}"
    assert names([]) == "none"
