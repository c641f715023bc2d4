"""The verdict's text and its table (every number of the one is a cell of the other), and
numbers for people: three significant digits and readable units."""

from __future__ import annotations

import math
import re

import pytest

from twin_cosim.gap.data.regimes import REGIMES
from twin_cosim.gap.floors.evidence import CalibrationFloor
from twin_cosim.gap.location import AxisSpan, Location
from twin_cosim.gap.verdict import (
    GAP_TABLE_HEADER,
    gap_table,
    names,
    number,
    parameters,
    percent,
    quantity,
    remaining_of,
    span_label,
    verdict_text,
)
from twin_cosim.measured import position_label

NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]\d+)?")


def numbers_in(text: str) -> list[str]:
    return NUMBER.findall(text)


def _shares(standstill: float, reversal: float) -> dict[str, dict[str, float]]:
    time = {"standstill": 0.0883, "reversal": 0.0241}
    energy = {"standstill": standstill, "reversal": reversal}
    return {
        name: {
            "time_share": time.get(name, 0.3),
            "energy_share": energy.get(name, 0.01),
            "enrichment": energy.get(name, 0.01) / time.get(name, 0.3),
        }
        for name in REGIMES
    }


def _floor(before: float, left: float) -> CalibrationFloor:
    return CalibrationFloor(before, left, (before**2 - left**2) ** 0.5, {})


SPANS = [
    AxisSpan(0.11629, 1.11629, 1, 0.8312, 2371.4, at_stroke_end=True),
    AxisSpan(22.6213, 23.1213, -1, 0.1841, 2290.0),
]
AFTER = Location(_shares(0.7412, 0.2401), _shares(0.5, 0.4), SPANS, {})
FLOORS = (2.6512e-08, 0.025712)  # m, A
CARRIAGE = position_label("current", 1e-3)  # a closed-loop run's carriage position


def _remaining():
    return remaining_of(
        _floor(41.83, 30.12),
        True,
        _floor(21.61, 18.31),
        True,
        AFTER,
        (1.50612, 0.286512),
        (0.785712, 0.0854512),
        FLOORS,
        "current",
        CARRIAGE,
    )


def test_every_number_of_the_verdict_is_a_cell_of_its_table():
    remaining = _remaining()
    text = verdict_text(True, [["stribeck"]], [], remaining)
    table = gap_table(remaining, _shares(0.52, 0.46), AFTER)
    assert table[0] == GAP_TABLE_HEADER
    cells = {n for row in table[1:] for cell in row for n in numbers_in(cell)}
    in_text = numbers_in(text)
    assert len(in_text) >= 12
    assert set(in_text) <= cells, set(in_text) - cells


def test_the_quadrature_sentence_says_so_with_its_unit():
    text = _remaining().text
    assert (
        "times the noise floor, calibration error within tolerance can explain 11.5 and "
        "leaves 18.3 (the two add in quadrature)" in text
    )
    assert "21.6 times the noise floor" in text


def test_spans_at_the_ends_of_travel_are_not_named_like_a_tight_spot():
    text = _remaining().text
    assert "0.116-1.12 mm, moving +, where the axis starts, stops or reverses (low speed; " in text
    assert "22.6-23.1 mm along the axis, moving - (18.4 % of the energy" in text
    rows = [row[0] for row in gap_table(_remaining(), _shares(0.52, 0.46), AFTER)]
    assert (
        "span 0.116-1.12 mm, moving +, where the axis starts, stops or reverses: share of the "
        "energy above the even level [%]" in rows
    )


def test_before_and_after_columns_of_the_regimes():
    table = gap_table(_remaining(), _shares(0.52, 0.46), AFTER)
    row = next(r for r in table if r[0].startswith("standstill: share"))
    assert row[1:] == ["52 %", "74.1 %"]
    assert next(r for r in table if r[0].startswith("gap energy above"))[1] == "100 %"


def _nothing_left(compared_before: float, compared_after: float, compared: str):
    """What is left when the gap is at the noise, the compared signal's RMS before and after
    given (A, or rad/s of an open-loop run)."""
    return remaining_of(
        _floor(41.8, 30.1),
        True,
        _floor(0.701, 0.700),
        False,
        AFTER,
        (1.3, compared_before),
        (0.02, compared_after),
        FLOORS,
        compared,
        position_label(compared, 1e-3),
    )


def test_nothing_left_names_no_place():
    remaining = _nothing_left(0.28, 0.005, "current")
    assert "located" not in remaining.text and "not significant" in remaining.text
    table = gap_table(remaining, _shares(0.52, 0.46), AFTER)
    assert not any(row[0].startswith(("standstill", "span")) for row in table)
    assert ["significant beyond noise and calibration error", "yes", "no"] in table


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


def test_the_noise_floors_are_named_where_the_verdict_names_them():
    """The bracket after "times the noise floor" holds the floors, not the residual left."""
    text = _remaining().text
    assert "21.6 times the noise floor (the floors: position 26.5 nm, current 0.0257 A RMS)" in text
    assert "a held-out gap of 0.786 um RMS in position and 0.0855 A RMS in current" in text
    table = gap_table(_remaining(), _shares(0.52, 0.46), AFTER)
    assert ["noise floor of the position (RMS)", "26.5 nm", "26.5 nm"] in table
    assert ["noise floor of the current (RMS)", "0.0257 A", "0.0257 A"] in table


@pytest.mark.parametrize(
    ("significant", "accepted", "below"),
    [
        (True, [["stribeck"], ["backlash_change", "coulomb_change"]], []),
        (True, [], ["inertia_change"]),
        (True, [], []),
        (False, [], []),
    ],
)
def test_the_verdict_opens_with_a_short_sentence(significant, accepted, below):
    text = verdict_text(significant, accepted, below, _remaining())
    first = text.split(". ", 1)[0]
    assert len(first.split()) <= 16, first
    assert text.endswith(".")
    if accepted:
        assert (
            first
            == "significant gap, explained in part: stribeck, {backlash_change, coulomb_change}"
        )


def test_a_gap_significant_only_by_a_figure_of_merit_says_so():
    remaining = remaining_of(
        _floor(41.8, 30.1),
        True,
        _floor(0.839, 0.698),
        True,
        Location(_shares(0.2, 0.1), _shares(0.2, 0.1), [], {}),
        (1.3, 0.28),
        (0.0216, 0.0881),
        FLOORS,
        "current",
        CARRIAGE,
        by_metrics_only=True,
    )
    assert "0.839 times the noise floor" in remaining.text
    assert "a significant gap (E_pk, ITAE or IAU off beyond what noise makes)" in remaining.text


def test_a_span_at_the_start_of_travel_reads_as_a_position():
    span = AxisSpan(-3.25e-05, 1.0, 0, 0.23, 1030.0, at_stroke_end=True)
    assert span_label(span).startswith("0-1 mm, both directions")


def test_an_open_loop_run_s_verdict_names_the_motor_speed_and_its_unit():
    remaining = _nothing_left(12.5, 0.4, "motor_speed")
    assert "0.400 rad/s RMS in motor speed" in remaining.text
    assert " A " not in remaining.text and "current" not in remaining.text
    rows = {row[0]: row[1:] for row in gap_table(remaining, _shares(0.52, 0.46), AFTER)}
    assert rows["motor speed gap, RMS [rad/s]"] == ["12.5", "0.400"]
    assert "noise floor of the motor speed (RMS)" in rows
    # the rotor's angle: the load position (1 mm per rad) over the travel per radian
    assert " um " not in remaining.text and "2.00e-05 rad RMS in angle" in remaining.text
    assert rows["angle gap, RMS [rad]"] == ["0.00130", "2.00e-05"]
    assert rows["noise floor of the angle (RMS)"] == ["26.5 urad", "26.5 urad"]
