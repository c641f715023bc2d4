"""Part programs: a G-code subset (RS274/NGC semantics, as LinuxCNC) read into path blocks.

The subset:

===========  ================================================================================
G17          XY plane for arcs (the only plane)
G00          rapid traverse: a straight line at the axes' velocity limits
G01          straight line at the programmed feed
G02, G03     arc clockwise / counter-clockwise seen from +Z, in the XY plane at constant Z;
             centre by I, J (offsets from the arc's start, always incremental: G91.1) or
             radius R (R > 0: at most 180 degrees, R < 0: more); a full circle by I, J with
             the end at the start
F            feed, units per minute (G94)
G90, G91     absolute / incremental coordinates of X, Y, Z
G20, G21     inch / millimetre
G04 P        dwell, P in seconds (LinuxCNC; Fanuc reads P in ms: give seconds)
G61, G61.1   exact stop: every block ends at rest (modal)
G64 [P [Q]]  blending (modal): the path keeps its speed through tangent joins and rounds
             corners, leaving each programmed corner by at most P (program units; without P,
             as far as the blocks allow); straight moves whose corners lie within Q (LinuxCNC's
             naive CAM tolerance, P/2 when not given, below P) of one line are traversed as
             that line, their corners blended within P - Q: the path stays within P
N            sequence number (ignored)
M02, M30     end of program (nothing after it may move)
===========  ================================================================================

Words of CAM output that do not move the axes are accepted and listed as ignored
(:attr:`Program.ignored`): ``O`` (program number), ``S`` (spindle speed), ``T`` (tool),
``M03``-``M09`` (spindle, tool change, coolant), ``G54`` (the first work offset: the machine's
own coordinates), ``G40``, ``G49``, ``G80`` (cancel cutter radius and tool length compensation
and canned cycles, none of which the subset has); ``G91.1`` and ``G94`` name what the subset
does anyway.

Comments in parentheses or after ``;`` are ignored. The path control mode (G61, G64) holds
until the program changes it; before it does, the machine scenario's (``interpolation.
path_mode``) holds. Anything else (another word, another G or M code, a word twice, two codes of
one modal group, an arc's Z change, an axis the machine lacks, a number in another format) is
refused before anything runs, naming the line and the word (:class:`ProgramError`).

Why not a parser from the package index: the ones that exist (``gcodeparser``, ``pygcode``)
drop what they do not understand without a word, lose modal motion lines and bare ``F`` words,
or are unmaintained; a strict subset needs every word accounted for, and its word grammar is a
regular expression.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from twin_cosim.contour.path import Arc, Element, Line
from twin_cosim.scenario.machine import PathControl

MM = 1e-3  # m per mm
INCH = 25.4e-3  # m per inch
_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\([^)]*\)")
# G codes by their number as written without leading zeros ("1", "61.1"): their modal group
_G_GROUPS = {
    "0": "motion",
    "1": "motion",
    "2": "motion",
    "3": "motion",
    "17": "plane",
    "20": "units",
    "21": "units",
    "90": "distance",
    "91": "distance",
    "91.1": "arc distance",
    "94": "feed mode",
    "61": "path control",
    "61.1": "path control",
    "64": "path control",
    "4": "dwell",
}
_G_IGNORED = {"40", "49", "54", "80"}  # no motion: cancel compensations and cycles, offset 1
_M_IGNORED = {3, 4, 5, 6, 7, 8, 9}  # spindle, tool change, coolant
_ENDS = (2, 30)
_ALLOWED = set("GXYZIJRFPNMOSTQ")
_IGNORED_LETTERS = set("OST")
SUBSET = (
    "G17, G00-G03, G04 P, G20, G21, G61, G61.1, G64 P Q, G90, G91, G91.1, G94, F, X, Y, Z, I, J, "
    "Q, R, N, M02, M30; ignored: O, S, T, M03-M09, G40, G49, G54, G80"
)
ARC_TOLERANCE = 5e-6  # m: largest difference of an arc's start and end radius (LinuxCNC's)
ARC_RELATIVE_TOLERANCE = 1e-3


class ProgramError(ValueError):
    """A part program is outside the subset or inconsistent; names the line and the word."""


@dataclass(frozen=True)
class Motion:
    """One motion block.

    Attributes
    ----------
    element : Line or Arc
        The programmed geometry, m.
    feed : float or None
        Programmed path speed, m/s; None for a rapid traverse (G00).
    line : int
        Line number in the program (1-based).
    path_control : PathControl or None
        The path control mode the program set for this block (G61, G64); None: the machine's.
    """

    element: Element
    feed: float | None
    line: int
    path_control: PathControl | None = None


@dataclass(frozen=True)
class Pause:
    """A dwell (G04) of ``duration`` s, from line ``line``."""

    duration: float
    line: int


Block = Motion | Pause


@dataclass(frozen=True)
class IgnoredWord:
    """A word accepted and ignored because it does not move the axes (``S12000`` on line 3)."""

    line: int
    word: str


@dataclass(frozen=True)
class Program:
    """A part program read into blocks.

    Attributes
    ----------
    blocks : tuple
        Motions and pauses in program order.
    start : tuple
        Position (X, Y, Z) in m where the program starts (the machine's position).
    source : str
        The file (or a label) named in errors.
    ignored : tuple of IgnoredWord
        The words that do not move the axes, accepted and ignored, in program order.
    """

    blocks: tuple[Block, ...]
    start: tuple[float, float, float]
    source: str
    ignored: tuple[IgnoredWord, ...] = ()

    @property
    def elements(self) -> tuple[Element, ...]:
        """The path's elements (motions only), in order."""
        return tuple(b.element for b in self.blocks if isinstance(b, Motion))

    def ignored_summary(self) -> str:
        """The ignored words for a reader, each with its lines: ``S12000 (line 3), M05 (lines
        40, 52)``; empty when none."""
        lines: dict[str, list[int]] = {}
        for ignored in self.ignored:
            lines.setdefault(ignored.word, []).append(ignored.line)
        return ", ".join(
            f"{word} (line{'s' if len(found) > 1 else ''} {', '.join(map(str, found))})"
            for word, found in lines.items()
        )


def read_program(
    path: Path | str, axes: tuple[str, ...] = ("X", "Y"), start=(0.0, 0.0, 0.0)
) -> Program:
    """Read a part program file; see :func:`parse_program`."""
    path = Path(path)
    try:
        text = path.read_text()
    except UnicodeDecodeError as exc:
        raise ProgramError(f"{path}: not a text (G-code) file: {exc}") from exc
    except OSError as exc:
        raise ProgramError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    return parse_program(text, str(path), axes, start)


@dataclass
class _State:
    """The interpreter's modal state, in m and m/s."""

    position: list[float]
    motion: int | None = None
    absolute: bool = True
    unit: float = MM
    feed: float | None = None
    path_control: PathControl | None = None
    ended: bool = False


def parse_program(
    text: str,
    source: str = "<program>",
    axes: tuple[str, ...] = ("X", "Y"),
    start: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Program:
    """Read a program's text into blocks.

    Parameters
    ----------
    text
        The program.
    source
        Named in errors.
    axes
        The machine's axes; a word for another axis is refused.
    start
        Position (X, Y, Z) in m where the program starts.

    Raises
    ------
    ProgramError
        ``SOURCE: line N: WORD: what is wrong`` for the first line outside the subset.
    """
    state = _State(position=[float(v) for v in start])
    blocks: list[Block] = []
    ignored: list[IgnoredWord] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        words = _words(raw, source, number)
        if not words:
            continue
        if state.ended:
            raise ProgramError(
                f"{source}: line {number}: {_text(*words[0])}: after the end of program (M02/M30)"
            )
        blocks.extend(_block(words, state, source, number, axes, ignored))
    return Program(tuple(blocks), tuple(float(v) for v in start), source, tuple(ignored))


def _words(raw: str, source: str, number: int) -> list[tuple[str, float, str]]:
    """The (letter, value, as written) words of one line, comments removed; the rest refused."""
    line = _COMMENT.sub(" ", raw.split(";", 1)[0]).strip()
    if line in ("", "%"):
        return []
    if "(" in line or ")" in line:
        raise ProgramError(f"{source}: line {number}: {line!r}: unbalanced parenthesis")
    words, at = [], 0
    for match in _WORD.finditer(line):
        gap = line[at : match.start()].strip()
        if gap:
            raise ProgramError(f"{source}: line {number}: {gap.split()[0]}: not a G-code word")
        letter, value = match.group(1).upper(), match.group(2)
        if letter not in _ALLOWED:
            raise ProgramError(
                f"{source}: line {number}: {match.group(0)}: word outside the subset ({SUBSET})"
            )
        words.append((letter, float(value), match.group(0)))
        at = match.end()
    rest = line[at:].strip()
    if rest:
        raise ProgramError(f"{source}: line {number}: {rest.split()[0]}: not a G-code word")
    return words


def _text(letter: str, value: float, written: str) -> str:
    return written.replace(" ", "")


def _block(
    words: list[tuple[str, float, str]],
    state: _State,
    source: str,
    number: int,
    axes: tuple[str, ...],
    ignored: list[IgnoredWord],
) -> list[Block]:
    """The blocks of one line, the modal state updated, its ignored words added to ``ignored``."""

    def fail(word: tuple[str, float, str], what: str) -> ProgramError:
        return ProgramError(f"{source}: line {number}: {_text(*word)}: {what}")

    groups: dict[str, tuple[str, float, str]] = {}
    values: dict[str, tuple[str, float, str]] = {}
    for word in words:
        letter, value, _ = word
        if letter == "N":
            continue
        if letter in _IGNORED_LETTERS:
            ignored.append(IgnoredWord(number, _text(*word)))
        elif letter == "G":
            code = f"{value:g}"
            if code in _G_IGNORED:
                ignored.append(IgnoredWord(number, _text(*word)))
                continue
            if code not in _G_GROUPS:
                raise fail(word, f"G code outside the subset ({SUBSET})")
            group = _G_GROUPS[code]
            if group in groups:
                raise fail(word, f"a second {group} code in one line")
            groups[group] = word
        elif letter == "M":
            if value in _M_IGNORED:
                ignored.append(IgnoredWord(number, _text(*word)))
                continue
            if value not in _ENDS:
                raise fail(word, f"M code outside the subset ({SUBSET})")
            groups["end"] = word
        else:
            if letter in values:
                raise fail(word, f"{letter} given twice in one line")
            values[letter] = word
    for letter in ("X", "Y", "Z"):
        if letter in values and letter not in axes:
            raise fail(values[letter], f"the machine has no {letter} axis (axes: {list(axes)})")
    if "units" in groups:
        state.unit = INCH if groups["units"][1] == 20 else MM
    if "distance" in groups:
        state.absolute = groups["distance"][1] == 90
    if "F" in values:
        if not values["F"][1] > 0:
            raise fail(values["F"], "expected a feed > 0 (units per minute)")
        state.feed = values["F"][1] * state.unit / 60.0
    _path_control(groups, values, state, fail)
    blocks: list[Block] = []
    if "dwell" in groups:
        blocks.append(_dwell(groups, values, fail, number))
    elif "P" in values and "path control" not in groups:
        raise fail(values["P"], "P belongs to a dwell (G04 P seconds) or to G64 (P tolerance)")
    if "motion" in groups:
        state.motion = int(groups["motion"][1])
    moves = any(k in values for k in ("X", "Y", "Z", "I", "J", "R"))
    if moves:
        if "dwell" in groups:
            raise fail(groups["dwell"], "a dwell and a motion in one line")
        blocks.append(_motion(values, state, fail, number))
    if "end" in groups:
        state.ended = True
    return blocks


def _path_control(groups, values, state: _State, fail) -> None:
    """G61, G61.1 and G64 [P [Q]] of one line into the modal state."""
    word = groups.get("path control")
    for letter in ("Q",) if word is None else ():
        if letter in values:
            raise fail(values[letter], "Q belongs to G64 (P tolerance Q naive CAM tolerance)")
    if word is None:
        return
    if word[1] != 64:
        for letter in ("P", "Q"):
            if letter in values:
                raise fail(values[letter], f"{letter} belongs to G64, not {_text(*word)}")
        state.path_control = PathControl("G61")
        return
    if "dwell" in groups:
        raise fail(word, "G64 and a dwell in one line (both take P)")
    tolerance, merge = math.inf, 0.0
    if "P" in values:
        if values["P"][1] < 0:
            raise fail(values["P"], "expected a tolerance >= 0 (program units)")
        tolerance = values["P"][1] * state.unit
        merge = tolerance / 2
    if "Q" in values:
        if "P" not in values:
            raise fail(values["Q"], "Q (naive CAM tolerance) needs P (G64 P<tolerance> Q<...>)")
        if not 0 <= values["Q"][1] < values["P"][1]:
            raise fail(values["Q"], "expected 0 <= Q < P (Q's merge and the blends share P)")
        merge = values["Q"][1] * state.unit
    state.path_control = PathControl("G64", tolerance, merge)


def _dwell(groups, values, fail, number: int) -> Pause:
    if "P" not in values:
        raise fail(groups["dwell"], "a dwell needs P (seconds)")
    if values["P"][1] < 0:
        raise fail(values["P"], "expected a dwell time >= 0 s")
    return Pause(values["P"][1], number)


def _motion(values, state: _State, fail, number: int) -> Motion:
    """The motion block of a line with axis or arc words."""
    if state.motion is None:
        first = next(values[k] for k in ("X", "Y", "Z", "I", "J", "R") if k in values)
        raise fail(first, "no motion mode active (G00, G01, G02 or G03 first)")
    start = list(state.position)
    end = list(start)
    for i, letter in enumerate(("X", "Y", "Z")):
        if letter in values:
            value = values[letter][1] * state.unit
            end[i] = value if state.absolute else start[i] + value
    if state.motion in (0, 1):
        for letter in ("I", "J", "R"):
            if letter in values:
                raise fail(values[letter], f"{letter} belongs to an arc (G02, G03)")
        element = Line(tuple(start), tuple(end))
    else:
        element = _arc(values, state, start, end, fail)
    feed = None
    if state.motion != 0:
        if state.feed is None:
            word = next(values[k] for k in ("X", "Y", "Z", "I", "J", "R") if k in values)
            raise fail(word, "no feed F given before this move")
        feed = state.feed
    state.position = end
    return Motion(element, feed, number, state.path_control)


def _arc(values, state: _State, start: list[float], end: list[float], fail) -> Arc:
    """The arc of a G02/G03 line from ``start`` to ``end`` (m)."""
    clockwise = state.motion == 2
    if "Z" in values and end[2] != start[2]:
        raise fail(values["Z"], "a Z change in an arc (a helix) is outside the subset")
    has_offsets = "I" in values or "J" in values
    if has_offsets and "R" in values:
        raise fail(values["R"], "an arc takes either R or I/J, not both")
    if not has_offsets and "R" not in values:
        word = next(values[k] for k in ("X", "Y") if k in values)
        raise fail(word, "an arc needs its centre (I, J) or radius (R)")
    dx, dy = end[0] - start[0], end[1] - start[1]
    if has_offsets:
        cx = start[0] + values.get("I", ("I", 0.0, ""))[1] * state.unit
        cy = start[1] + values.get("J", ("J", 0.0, ""))[1] * state.unit
        radius = math.hypot(start[0] - cx, start[1] - cy)
        end_radius = math.hypot(end[0] - cx, end[1] - cy)
        word = values["I"] if "I" in values else values["J"]
        if radius == 0.0:
            raise fail(word, "the arc's centre is its start point (radius 0)")
        if abs(end_radius - radius) > max(ARC_TOLERANCE, ARC_RELATIVE_TOLERANCE * radius):
            raise fail(
                word,
                f"the end point is {end_radius / MM:.6g} mm from the centre, the start "
                f"{radius / MM:.6g} mm: not on one circle",
            )
    else:
        radius_word = values["R"]
        signed = radius_word[1] * state.unit
        chord = math.hypot(dx, dy)
        if chord == 0.0:
            raise fail(radius_word, "a full circle needs I, J (R gives no centre)")
        if abs(signed) < chord / 2 - ARC_TOLERANCE:
            raise fail(
                radius_word,
                f"radius {abs(signed) / MM:.6g} mm is below half the chord {chord / 2 / MM:.6g} mm",
            )
        radius = abs(signed)
        height = math.sqrt(max(radius**2 - (chord / 2) ** 2, 0.0))
        # centre left of the chord for (G03, R > 0) and (G02, R < 0): the short arc or the long
        left = (not clockwise) == (signed > 0)
        sign = 1.0 if left else -1.0
        cx = start[0] + dx / 2 - sign * height * dy / chord
        cy = start[1] + dy / 2 + sign * height * dx / chord
    a0 = math.atan2(start[1] - cy, start[0] - cx)
    a1 = math.atan2(end[1] - cy, end[0] - cx)
    if clockwise:
        sweep = -((a0 - a1) % (2 * math.pi))
    else:
        sweep = (a1 - a0) % (2 * math.pi)
    if abs(sweep) < 1e-12:  # end at the start: a full circle
        sweep = -2 * math.pi if clockwise else 2 * math.pi
    return Arc((cx, cy), radius, a0, sweep, start[2])
