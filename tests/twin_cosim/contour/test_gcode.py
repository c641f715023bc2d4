"""Part programs: the subset's semantics, and every line outside it refused by line and word."""

from __future__ import annotations

import math

import pytest

from twin_cosim.contour.gcode import Arc, Line, Motion, Pause, ProgramError, parse_program


def _motions(text: str, axes=("X", "Y")):
    return [b for b in parse_program(text, axes=axes).blocks if isinstance(b, Motion)]


def test_lines_feeds_units_and_incremental_coordinates():
    blocks = parse_program(
        "G21 G90\nG00 X10\nG01 Y5 F600\nG91 X-4\nG20 G01 X1 F10\nG04 P0.25\nM30\n"
    ).blocks
    rapid, feed, incremental, inch, dwell = blocks
    assert rapid.feed is None and rapid.element == Line((0, 0, 0), (0.01, 0, 0))
    assert feed.element.end == (0.01, 0.005, 0.0) and math.isclose(feed.feed, 0.01)  # 600 mm/min
    assert incremental.element.end == pytest.approx((0.006, 0.005, 0.0))
    assert inch.element.end == pytest.approx((0.006 + 0.0254, 0.005, 0.0))
    assert math.isclose(inch.feed, 10 * 0.0254 / 60)
    assert dwell == Pause(0.25, 6)


def test_arcs_by_centre_offsets_and_by_radius():
    ccw, cw_long, full = _motions(
        "G01 X10 F1000\nG03 X0 Y10 R10\nG02 X10 Y0 R-10\nG03 X10 Y0 I-10 J0\n"
    )[1:]
    assert isinstance(ccw.element, Arc)
    assert ccw.element.centre == pytest.approx((0.0, 0.0), abs=1e-15)
    assert math.isclose(ccw.element.sweep, math.pi / 2)
    assert cw_long.element.centre == pytest.approx((0.01, 0.01))  # R < 0: more than 180 degrees
    assert math.isclose(cw_long.element.sweep, -1.5 * math.pi)
    assert math.isclose(full.element.sweep, 2 * math.pi)
    assert full.element.end == pytest.approx((0.01, 0.0, 0.0))
    short_cw = _motions("G01 X10 F1000\nG02 X0 Y10 R10\n")[1].element
    assert short_cw.centre == pytest.approx((0.01, 0.01)) and short_cw.sweep == pytest.approx(
        -math.pi / 2
    )


def test_comments_numbers_and_modal_motion():
    motions = _motions("%\n(part) N10 G01 X1 F100 ; go\nX2 (modal)\nY1\n%\n")
    ends = [coordinate for m in motions for coordinate in m.element.end[:2]]
    assert ends == pytest.approx([0.001, 0, 0.002, 0, 0.002, 0.001])


@pytest.mark.parametrize(
    ("text", "line", "word"),
    [
        ("G01 X1 F100\nG01 X1 Q2", 2, "Q2"),
        ("G18", 1, "G18"),
        ("G01 X1.5e1 F100", 1, "e1"),
        ("G01 X1", 1, "X1"),
        ("X1", 1, "X1"),
        ("G01 Z1 F100", 1, "Z1"),
        ("G01 X1 X2 F1", 1, "X2"),
        ("G00 G01 X1 F1", 1, "G01"),
        ("M98 P100", 1, "M98"),
        ("G01 X1 F100\nG02 X2 Y0 R0.1", 2, "R0.1"),
        ("G01 X10 F100\nG02 X0 Y0 I-4 J0\n", 2, "I-4"),
        ("G01 X10 F100\nG03 X0 Y10 R10 I1", 2, "R10"),
        ("G04", 1, "G04"),
        ("G01 X1 F100\nM30\nG01 X2", 3, "G01"),
        ("G01 X1 F0", 1, "F0"),
        ("G01 X1 F100 #", 1, "#"),
        ("G01 X1 F100 P2", 1, "P2"),
    ],
)
def test_a_line_outside_the_subset_is_refused_naming_line_and_word(text, line, word):
    with pytest.raises(ProgramError) as error:
        parse_program(text, "part.nc")
    message = str(error.value)
    assert message.startswith("part.nc: line ")
    if line is not None:
        assert f"line {line}:" in message
    assert word in message


def test_an_arc_with_a_z_change_is_refused_on_a_three_axis_machine():
    with pytest.raises(ProgramError, match="line 2: Z1: .*helix"):
        parse_program("G01 X1 F100\nG02 X0 Y1 Z1 R1", axes=("X", "Y", "Z"))
