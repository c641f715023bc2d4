"""Part programs: the subset's semantics, CAM words accepted and listed, path control, and every
line outside the subset refused by line and word."""

from __future__ import annotations

import math

import pytest

from twin_cosim.contour.gcode import Arc, Line, Motion, Pause, ProgramError, parse_program
from twin_cosim.scenario.machine import PathControl


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


CAM = """%
O1001 (POCKET)
N10 G17 G21 G40 G49 G80 G90 G94
N20 T1 M06
N30 S12000 M03
N40 G54 M08
N50 G64 P0.005
N60 G00 X5. Y0.
N70 G01 X10. F1200.
N80 Y5.
N90 M09
N100 M05
N110 M30
%
"""


def test_cam_words_that_do_not_move_the_axes_are_accepted_and_listed():
    program = parse_program(CAM, "cam.nc")
    assert [m.element.end[:2] for m in _motions(CAM)] == [
        pytest.approx((0.005, 0.0)),
        pytest.approx((0.01, 0.0)),
        pytest.approx((0.01, 0.005)),
    ]
    words = [(w.line, w.word) for w in program.ignored]
    assert words == [
        (2, "O1001"),
        (3, "G40"),
        (3, "G49"),
        (3, "G80"),
        (4, "T1"),
        (4, "M06"),
        (5, "S12000"),
        (5, "M03"),
        (6, "G54"),
        (6, "M08"),
        (11, "M09"),
        (12, "M05"),
    ]
    assert program.ignored_summary().startswith("O1001 (line 2), G40 (line 3)")


def test_g64_and_g61_are_modal_path_control_with_p_and_q_in_program_units():
    blocks = parse_program(
        "G01 X1 F100\nG64 P0.01\nX2\nG64 P0.02 Q0.005\nX3\nG61\nX4\nG64\nX5\nG20 G64 P0.001\nX6"
    ).blocks
    controls = [b.path_control for b in blocks]
    assert controls[0] is None  # before the program sets one: the machine's
    assert controls[1] == PathControl("G64", 1e-5, 5e-6)  # Q: P/2 by default
    assert controls[2] == PathControl("G64", 2e-5, 5e-6)
    assert controls[3] == PathControl("G61")
    assert controls[4].tolerance == math.inf and controls[4].merge_tolerance == 0.0
    assert controls[5].tolerance == pytest.approx(0.0254e-3)  # inch
    assert parse_program("G61.1\nG01 X1 F100").blocks[0].path_control == PathControl("G61")


@pytest.mark.parametrize(
    ("text", "word", "what"),
    [
        ("G64 Q0.01\nG01 X1 F100", "Q0.01", "needs P"),
        ("G64 P0.01 Q0.02\nG01 X1 F100", "Q0.02", "0 <= Q < P"),
        ("G64 P-1\nG01 X1 F100", "P-1", ">= 0"),
        ("G61 P0.01", "P0.01", "belongs to G64"),
        ("G04 G64 P1", "G64", "dwell"),
        ("G01 X1 F100 Q2", "Q2", "belongs to G64"),
        ("G43 H1 Z5", "H1", "outside the subset"),
        ("G43 Z5", "G43", "outside the subset"),
        ("G55", "G55", "outside the subset"),
    ],
)
def test_path_control_words_are_checked(text, word, what):
    with pytest.raises(ProgramError) as error:
        parse_program(text, "p.nc", axes=("X", "Y", "Z"))
    assert word in str(error.value) and what in str(error.value)
