"""The verdict's text and its table: every number of the one is a cell of the other."""

from __future__ import annotations

import re

from twin_cosim.gap.calibration import CalibrationFloor
from twin_cosim.gap.location import AxisSpan, Location
from twin_cosim.gap.regimes import REGIMES
from twin_cosim.gap.verdict import GAP_TABLE_HEADER, gap_table, remaining_of, verdict_text

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


def _remaining():
    return remaining_of(
        _floor(41.83, 30.12),
        True,
        _floor(21.61, 18.31),
        True,
        AFTER,
        (1.50612, 0.286512),
        (0.785712, 0.0854512),
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


def test_nothing_left_names_no_place():
    remaining = remaining_of(
        _floor(41.8, 30.1), True, _floor(0.701, 0.700), False, AFTER, (1.3, 0.28), (0.02, 0.005)
    )
    assert "located" not in remaining.text and "not significant" in remaining.text
    table = gap_table(remaining, _shares(0.52, 0.46), AFTER)
    assert not any(row[0].startswith(("standstill", "span")) for row in table)
    assert ["significant beyond noise and calibration error", "yes", "no"] in table
