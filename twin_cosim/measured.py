"""Measured runs: files of a real (or virtual) axis, the units of their signals, their checks,
and their match to a scenario.

**Units of measured signals**: the units a file may carry, what each measures and its factor to
the SI unit the twin computes in.

A measured file says the unit of a column in its header (``x [mm]``, ``current (mA)``) or in a
drive trace's metadata (TwinCAT Scope's ``Unit`` row); :func:`to_si` converts the values. Each
signal of a run measures one quantity (:data:`QUANTITY_OF`: ``x`` a length, ``motor_speed`` an
angular speed, ...), so that a unit of another quantity (``x [rpm]``) is refused rather than
guessed, as is a unit this table does not know. A column without a unit is in the signal's SI
unit (:data:`SI_UNIT`), the documented default of the project's CSV format.

**Measured runs.** One reader (:func:`read_measured`) for every format; each gives a
:class:`MeasuredRun` in the SI units of the twin (a unit per signal):

- **CSV** (the project's format): ``t`` [s], ``x_ref`` [m], ``x`` [m] (measured load
  position), ``current`` [A]; optional ``motor_speed`` [rad/s], ``motor_angle`` [rad],
  ``load_speed`` [m/s], ``input_torque`` and ``measured_torque`` [N.m]. A header may carry each
  column's unit (``t [ms]``, ``x [mm]``, ``current (mA)``, ``motor_speed [rpm]``; the units of
  :data:`QUANTITY_OF`), converted on reading; a column without a unit is in the SI
  unit above; an unknown unit, or one of another quantity, is an error naming the column. Other
  names map onto these by a column map (``--columns x=ActPos,t=Time``, or the scenario's
  ``measured_columns``). Extra columns are kept when their header names a known unit (another
  run's disturbance or drive signal) and otherwise ignored.
- **TwinCAT Scope CSV export** (Beckhoff TwinCAT 3 Scope View, *Export to CSV*): a header block
  (the scope's ``Name``, ``File``, ``Starttime of export`` and ``Endtime of export``), a blank
  line, one row per channel property (``Name``, ``SymbolName``, ``SampleTime[ms]``, ``Unit``,
  ... ; each row a key and a value per channel, the key repeated at the start of every group of
  channels that share a time column), a blank line, then the samples: per group its time in ms
  and its channels' values, tab- or semicolon-separated, decimal comma or point, an optional
  ``EOF`` line. Channels are named by their ``Name`` (or ``SymbolName``) through the column map
  and converted from their ``Unit`` (``mm (Millimeter)``: the unit before its name in
  parentheses; ``(None)``: the signal's SI unit); the channels a run uses must be sampled at
  the same times (one time column per channel, or one per group). Example:
  ``docs/examples/twincat_scope_export.csv``.
- **EMPS benchmark .mat** (as published, Janot, Gautier, Brunot 2019): ``t`` [s], ``qg``
  (reference, m), ``qm`` (motor position in load units, m), ``vir`` (drive command, V) and the
  scalars ``gtau`` [N/V], ``kp`` [1/s], ``kv`` [V/(m/s)]; the validation run also holds
  ``pulses_N`` (N). ``current`` then holds the drive command vir in V.
- **HSM150 .mat** (the HSM150 bench's runs as published): a 7-column array ``data`` of time
  [s], position reference [rad], position [rad], velocity [rad/s], input torque [N.m], measured
  torque [N.m] and motor current [A], and the bench's scalars (``J``, ``B``, ``Cu``, ...): the
  signals ``t``, ``angle_ref``, ``motor_angle``, ``motor_speed``, ``input_torque``,
  ``measured_torque``, ``current``. An open-loop run: the plant is driven by one of its signals
  (a scenario's ``reference.drive``), and its position is the rotor's angle.

Time must be strictly increasing and regular. Every problem gets an error naming the file, the
column and what was expected, or, where the data can still be used, an explicit warning that the
report repeats.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord

# Unit (as written in a file) -> (quantity, factor to the quantity's SI unit).
UNITS: dict[str, tuple[str, float]] = {
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "us": ("time", 1e-6),
    "m": ("length", 1.0),
    "mm": ("length", 1e-3),
    "um": ("length", 1e-6),
    "µm": ("length", 1e-6),
    "nm": ("length", 1e-9),
    "rad": ("angle", 1.0),
    "mrad": ("angle", 1e-3),
    "deg": ("angle", math.pi / 180.0),
    "°": ("angle", math.pi / 180.0),
    "rev": ("angle", 2.0 * math.pi),
    "rad/s": ("angular speed", 1.0),
    "deg/s": ("angular speed", math.pi / 180.0),
    "rpm": ("angular speed", 2.0 * math.pi / 60.0),
    "1/min": ("angular speed", 2.0 * math.pi / 60.0),
    "m/s": ("speed", 1.0),
    "mm/s": ("speed", 1e-3),
    "mm/min": ("speed", 1e-3 / 60.0),
    "m/min": ("speed", 1.0 / 60.0),
    "A": ("current", 1.0),
    "mA": ("current", 1e-3),
    "V": ("voltage", 1.0),
    "mV": ("voltage", 1e-3),
    "N": ("force", 1.0),
    "N.m": ("torque", 1.0),
    "Nm": ("torque", 1.0),
    "N·m": ("torque", 1.0),
    "mN.m": ("torque", 1e-3),
    "mNm": ("torque", 1e-3),
}
# The SI unit of each quantity (the unit of the twin's records).
QUANTITY_SI = {
    "time": "s",
    "length": "m",
    "angle": "rad",
    "angular speed": "rad/s",
    "speed": "m/s",
    "current": "A",
    "voltage": "V",
    "force": "N",
    "torque": "N.m",
}
# The quantities each signal of a measured run may carry (the command: a current, or the
# voltage of a drive commanded in V, as EMPS's).
QUANTITY_OF: dict[str, tuple[str, ...]] = {
    "t": ("time",),
    "x_ref": ("length",),
    "x": ("length",),
    "current": ("current", "voltage"),
    "motor_speed": ("angular speed",),
    "motor_angle": ("angle",),
    "angle_ref": ("angle",),
    "load_speed": ("speed",),
    "input_torque": ("torque",),
    "measured_torque": ("torque",),
}
# A signal's unit when its column gives none.
SI_UNIT = {name: QUANTITY_SI[quantities[0]] for name, quantities in QUANTITY_OF.items()}
_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*(?:\[(?P<bracket>[^\]]*)\]|\((?P<paren>[^)]*)\))\s*$")


class UnitError(ValueError):
    """A unit is unknown, or measures another quantity than its signal; the message names the
    column."""


def split_header(header: str) -> tuple[str, str | None]:
    """A column header as (name, unit): ``"x [mm]"`` and ``"x (mm)"`` give ``("x", "mm")``,
    ``"x"`` gives ``("x", None)``."""
    match = _HEADER.match(header)
    if match is None:
        return header.strip(), None
    unit = match.group("bracket") if match.group("bracket") is not None else match.group("paren")
    return match.group("name"), unit.strip()


def to_si(values, unit: str, signal: str, column: str):
    """``values`` in ``unit`` as the SI unit of their quantity, and that unit.

    Parameters
    ----------
    values
        Numbers (a float or a numpy array).
    unit
        The unit the file gives (one of :data:`UNITS`).
    signal
        The signal the column holds (a key of :data:`QUANTITY_OF`), or any other name for a
        column the twin does not interpret (its unit must still be known).
    column
        The column as the file names it, for messages.

    Raises
    ------
    UnitError
        For a unit not in :data:`UNITS`, or one of another quantity than the signal's.
    """
    known = UNITS.get(unit.strip())
    if known is None:
        raise UnitError(
            f"column {column!r}: unknown unit {unit!r}; expected one of {', '.join(UNITS)}"
        )
    quantity, factor = known
    expected = QUANTITY_OF.get(signal)
    if expected is not None and quantity not in expected:
        units = [u for u, (q, _) in UNITS.items() if q in expected]
        raise UnitError(
            f"column {column!r}: unit {unit!r} is a {quantity}, but {signal} is a "
            f"{' or a '.join(expected)} (units {', '.join(units)})"
        )
    return values * factor, QUANTITY_SI[quantity]


REQUIRED = ("t", "x_ref", "x", "current")
# An open-loop run needs its motor speed and a position: x, or the rotor's angle.
OPEN_LOOP_REQUIRED = ("t", "motor_speed")
OPEN_LOOP_POSITIONS = ("x", "motor_angle")
SIGNALS = tuple(QUANTITY_OF)
REGULARITY_TOLERANCE = 1e-3  # relative jitter of the sample period
MIN_SAMPLES = 100
UNIT_FACTORS = {1e3: "mm instead of m", 1e6: "um instead of m"}
# The columns of an open-loop comparison: the position and the motor speed (a closed-loop
# run's second signal is its command, ``current``).
OPEN_LOOP_COMPARED = "motor_speed"
# The commanded input of an open-loop run, when it has one: its levels are the experiment's.
EXPERIMENT_INPUT = "input_torque"
CLOSED_LOOP_COMPARED = "current"


@dataclass(frozen=True)
class PositionLabel:
    """How a report names and shows the position it compares: a carriage position (in um in
    its tables), or the angle of an open-loop rotor, its load position over the travel per
    radian (in rad).

    Attributes
    ----------
    words : str
        ``position`` or ``angle``.
    si_unit : str
        ``m`` or ``rad``.
    per_m : float
        ``si_unit`` per m of load position (1, or 1 / travel_per_rad).
    unit : str
        The tables' unit: ``um`` or ``rad``.
    per_um : float
        ``unit`` per um of load position (1, or 1e-6 / travel_per_rad).
    axis_words : str
        What a figure's position axis shows: ``carriage position`` or ``rotor angle turned``.
    travel : bool
        Whether the position runs along an axis (a carriage), where spans of the travel mean
        something; a rotor turns, and the angle it has turned is no place on an axis.
    """

    words: str
    si_unit: str
    per_m: float
    unit: str
    per_um: float
    axis_words: str
    travel: bool

    def figure_scale(self, largest_m: float) -> tuple[str, float]:
        """The unit a figure shows positions in, and its factor per m of load position, for
        positions up to ``largest_m`` (m): a carriage in um, or in mm beyond 10 mm; a rotor's
        angle in rad."""
        if not self.travel:
            return self.si_unit, self.per_m
        return ("mm", 1e3) if largest_m > 1e-2 else ("um", 1e6)


def position_label(compared: str, travel_per_rad: float) -> PositionLabel:
    """The position a run compares (:attr:`MeasuredRun.compared` names its other signal): the
    rotor's angle for an open-loop run (``travel_per_rad`` m of load position per rad), the
    carriage position otherwise."""
    if compared == OPEN_LOOP_COMPARED:
        return PositionLabel(
            "angle",
            "rad",
            1.0 / travel_per_rad,
            "rad",
            1e-6 / travel_per_rad,
            "rotor angle turned",
            travel=False,
        )
    return PositionLabel("position", "m", 1.0, "um", 1.0, "carriage position", travel=True)


def compared_label(signal: str) -> tuple[str, str]:
    """Words and SI unit of a signal compared beside the position (:attr:`MeasuredRun.compared`):
    ``("current", "A")`` of a closed-loop run, ``("motor speed", "rad/s")`` of an open-loop one."""
    return signal.replace("_", " "), SI_UNIT[signal]


def _signal(name: str, doc: str) -> property:
    """A signal of a run's record as an attribute of the run (the column itself, a view);
    MeasuredDataError naming the file when the run has none."""

    def get(run: MeasuredRun) -> np.ndarray:
        values = run.record.get(name)
        if values is None:
            raise MeasuredDataError(
                f"{run.source}: no column {name!r} (it holds {list(run.record.columns)})"
                + (
                    "; an open-loop run (a rotor's angle and speed) needs a scenario with "
                    "reference.drive"
                    if "motor_angle" in run.record.columns
                    else ""
                )
            )
        return values

    return property(get, doc=doc)


class MeasuredDataError(ValueError):
    """A measured file (a run; a frequency response, :mod:`twin_cosim.frequency.calibration`)
    cannot be used; the message names the file, the column (or the frequency) and the problem."""


@dataclass(frozen=True)
class MeasuredRun:
    """One measured run on a regular time grid.

    Attributes
    ----------
    source : str
        File it came from.
    record : RunRecord
        The samples, SI units: ``t`` [s], ``x_ref`` and ``x`` (reference and measured carriage
        position, m), ``current`` (current command, A; the drive command in V for an EMPS run),
        optionally ``motor_speed`` [rad/s], ``motor_angle`` [rad] and further signals of the
        file (e.g. EMPS ``pulses_N``, N; HSM150 ``input_torque``, N.m).
    warnings : list of str
        Problems that did not stop the diagnosis.
    scalars : dict
        Numbers the file holds besides its signals (e.g. EMPS ``gtau``, ``kp``, ``kv``).
    drive : str or None
        For an open-loop run: the signal that drove the plant (its current command, in place of
        a controller's); None for a run in closed loop.
    """

    source: str
    record: RunRecord
    warnings: list[str] = field(default_factory=list)
    scalars: dict[str, float] = field(default_factory=dict)
    drive: str | None = None

    @classmethod
    def from_signals(
        cls,
        source: str,
        signals: Mapping[str, np.ndarray],
        units: Mapping[str, str] | None = None,
        scalars: Mapping[str, float] | None = None,
    ) -> MeasuredRun:
        """A run of ``signals`` by name (``t``, ``x_ref``, ``x``, ``current`` and any further
        ones), in the SI units of :data:`twin_cosim.measured.SI_UNIT` unless ``units``
        names another."""
        known = {name: unit for name, unit in SI_UNIT.items() if name in signals}
        record = RunRecord.from_columns(signals, {**known, **(units or {})})
        return cls(source, record, scalars=dict(scalars or {}))

    t = _signal("t", "Sample times, s.")
    x_ref = _signal("x_ref", "Reference carriage position, m.")
    x = _signal("x", "Measured carriage position, m.")
    current = _signal("current", "Current command, A (the drive command, V, of an EMPS run).")

    @property
    def motor_speed(self) -> np.ndarray | None:
        """Measured motor speed, rad/s (None when the file has none)."""
        return self.record.get("motor_speed")

    @property
    def experiment_signal(self) -> str | None:
        """The name of an open-loop run's commanded input, whose levels make the experiment:
        its ``input_torque`` when it has one, whatever signal drives the plant (a measured
        torque is that command with the drive's error and the sensor's noise, a new value every
        sample), else its drive signal; None for a run in closed loop."""
        if self.drive is None:
            return None
        return EXPERIMENT_INPUT if EXPERIMENT_INPUT in self.record.columns else self.drive

    @property
    def experiment_input(self) -> np.ndarray | None:
        """An open-loop run's commanded input (:attr:`experiment_signal`), in its unit; None
        for a run in closed loop."""
        name = self.experiment_signal
        return None if name is None else self.record[name]

    @property
    def compared(self) -> str:
        """The signal compared beside the position: the motor speed of an open-loop run, the
        command (``current``) of a closed-loop one."""
        return OPEN_LOOP_COMPARED if self.drive else CLOSED_LOOP_COMPARED

    @property
    def period(self) -> float:
        """Sample period, s."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    def select(self, mask: np.ndarray) -> MeasuredRun:
        """The samples where ``mask`` is True (same source, warnings, scalars and drive)."""
        return MeasuredRun(
            self.source, self.record.rows(mask), self.warnings, self.scalars, self.drive
        )

    def with_signals(self, signals: Mapping[str, np.ndarray]) -> MeasuredRun:
        """The run with ``signals`` (by name, one value per sample) in place of its own."""
        return MeasuredRun(
            self.source, self.record.with_columns(signals), self.warnings, self.scalars, self.drive
        )

    def open_loop(self, drive: str, travel_per_rad: float) -> MeasuredRun:
        """The run as an open-loop run driven by its signal ``drive``: ``x`` (m) from its
        ``motor_angle`` (rad) times ``travel_per_rad`` (m/rad) when it has no ``x``, and its
        measured motion as its reference (``x_ref`` = ``x``: what the twin must reproduce).

        Raises
        ------
        MeasuredDataError
            When it lacks the drive signal, the motor speed or a position.
        """
        missing = [n for n in (drive, *OPEN_LOOP_REQUIRED) if n not in self.record.columns]
        if not any(n in self.record.columns for n in OPEN_LOOP_POSITIONS):
            missing.append(" or ".join(OPEN_LOOP_POSITIONS))
        if missing:
            raise MeasuredDataError(
                f"{self.source}: an open-loop run driven by {drive!r} needs the column(s) "
                f"{missing}; it holds {list(self.record.columns)}"
            )
        x = self.record.get("x")
        if x is None:
            x = self.record["motor_angle"] * travel_per_rad
        units = {"x": "m", "x_ref": "m"}
        record = self.record.with_columns({"x": x, "x_ref": x}, units)
        return MeasuredRun(self.source, record, self.warnings, self.scalars, drive)


def parse_columns(text: str, option: str = "--columns") -> dict[str, str]:
    """A column map ``signal=column,signal=column`` (``x=ActPos,t=Time``) as a mapping from the
    run's signals (:data:`SIGNALS`) to the file's column names.

    Raises
    ------
    ValueError
        Naming the option and the item for an item that is not ``signal=name`` or a signal the
        twin does not know.
    """
    found = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        signal, equals, column = (p.strip() for p in item.partition("="))
        if not equals or not signal or not column:
            raise ValueError(f"{option} {text!r}: {item!r} must be signal=column")
        if signal not in SIGNALS:
            raise ValueError(
                f"{option} {text!r}: {signal!r} is not a signal; expected one of {SIGNALS}"
            )
        found[signal] = column
    return found


def _numeric_column(path: Path, column: str, raw) -> np.ndarray:
    """A column of text or numbers as float64; MeasuredDataError naming the bad lines."""
    import pandas as pd

    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(values))
    if len(bad):
        rows = ", ".join(str(r + 2) for r in bad[:5])  # +2: header line and 1-based rows
        raise MeasuredDataError(
            f"{path}: column {column!r} has {len(bad)} missing, non-numeric or non-finite "
            f"value(s) (file lines {rows}{', ...' if len(bad) > 5 else ''}); "
            "gaps must be filled"
        )
    return values


def _roles(path: Path, headers: list[str], columns: Mapping[str, str]) -> dict[str, str]:
    """Signal -> header of the file: the column map's names first, then the signals' own."""
    names = {split_header(h)[0]: h for h in headers}
    found = {}
    for signal, name in columns.items():
        header = names.get(name) if name in names else (name if name in headers else None)
        if header is None:
            raise MeasuredDataError(
                f"{path}: the column map names {name!r} for {signal!r}, but the file has no such "
                f"column (it has {headers})"
            )
        found[signal] = header
    taken = set(found.values())
    for signal in SIGNALS:
        if signal not in found and signal in names and names[signal] not in taken:
            found[signal] = names[signal]
    return found


def _converted(path: Path, signal: str, header: str, values: np.ndarray) -> tuple[np.ndarray, str]:
    """A column in its header's unit (the signal's SI unit without one) as SI values."""
    _, unit = split_header(header)
    if unit is None or unit == "":
        return values, SI_UNIT.get(signal, "1")
    try:
        return to_si(values, unit, signal, header)
    except UnitError as exc:
        raise MeasuredDataError(f"{path}: {exc}") from None


def _checked_signals(
    path: Path, signals: dict[str, np.ndarray], open_loop: bool, found: list[str]
) -> None:
    """The signals a run of its kind needs; MeasuredDataError naming what is missing."""
    if open_loop:
        missing = [c for c in OPEN_LOOP_REQUIRED if c not in signals]
        if not any(p in signals for p in OPEN_LOOP_POSITIONS):
            missing.append(" or ".join(OPEN_LOOP_POSITIONS))
        expected = "t [s], motor_speed [rad/s] and x [m] or motor_angle [rad]"
    else:
        missing = [c for c in REQUIRED if c not in signals]
        expected = "t [s], x_ref [m], x [m], current [A] (optional motor_speed [rad/s])"
    if missing:
        raise MeasuredDataError(
            f"{path}: missing column(s) {missing}; expected {expected}, found {found} (other "
            "names: a column map, --columns signal=name)"
        )


def read_measured_csv(
    path: Path | str, columns: Mapping[str, str] | None = None, open_loop: bool = False
) -> MeasuredRun:
    """Read and check a measured-run CSV (units from its header, names by ``columns``).

    Raises
    ------
    MeasuredDataError
        On an unreadable file, missing columns, unknown units, non-numeric or non-finite values
        (rows named), non-monotonic or irregular time, or too few samples.
    """
    import pandas as pd  # a CSV run only: pandas stays off the start of other commands

    path = Path(path)
    if _is_twincat_export(path):
        return read_twincat_scope_csv(path, columns, open_loop)
    try:
        table = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as CSV: {exc}") from exc
    headers = [str(c) for c in table.columns]
    roles = _roles(path, headers, columns or {})
    _checked_signals(path, dict.fromkeys(roles), open_loop, headers)
    signals, units = {}, {}
    for signal, header in roles.items():
        values = _numeric_column(path, header, table[header])
        signals[signal], units[signal] = _converted(path, signal, header, values)
    for header in headers:
        name, unit = split_header(header)
        if header in roles.values() or not unit or name in signals:
            continue
        try:  # an extra signal of a known unit (a disturbance, a drive signal)
            values, units[name] = to_si(
                _numeric_column(path, header, table[header]), unit, name, header
            )
        except (UnitError, MeasuredDataError):
            continue
        signals[name] = values
    run = MeasuredRun.from_signals(str(path), signals, units)
    check_time(run)
    return run


_TWINCAT_EOF = "EOF"


def _is_twincat_export(path: Path) -> bool:
    """A TwinCAT Scope CSV export: its first line is the scope's ``Name`` and a
    ``SampleTime[ms]`` row follows before the samples."""
    try:
        with path.open(encoding="utf-8-sig", errors="replace") as handle:
            head = [handle.readline() for _ in range(40)]
    except OSError:
        return False
    first = re.split(r"[\t;]", head[0].strip(), maxsplit=1)[0] if head and head[0] else ""
    return first == "Name" and any(re.match(r"SampleTime\[ms\][\t;]", h) for h in head)


def _twincat_number(text: str, decimal_comma: bool) -> float:
    text = text.strip()
    if decimal_comma:
        text = text.replace(".", "").replace(",", ".")
    return float(text) if text else float("nan")


def _blocks(lines: list[str]) -> list[list[int]]:
    """The indices of the lines of each block of non-blank lines (blocks parted by one or more
    blank lines)."""
    blocks: list[list[int]] = []
    previous_blank = True
    for index, line in enumerate(lines):
        if not line.strip():
            previous_blank = True
            continue
        if previous_blank:
            blocks.append([])
        blocks[-1].append(index)
        previous_blank = False
    return blocks


def _twincat_unit(cell: str) -> str:
    """A TwinCAT Scope ``Unit`` cell as a unit: ``"mm (Millimeter)"`` gives ``"mm"``,
    ``"(None)"`` and an empty cell give ``""``."""
    return re.sub(r"\s*\([^)]*\)\s*$", "", cell.strip())


def read_twincat_scope_csv(
    path: Path | str, columns: Mapping[str, str] | None = None, open_loop: bool = False
) -> MeasuredRun:
    """Read a TwinCAT Scope CSV export (see the module docstring) as a measured run.

    Channels become the run's signals through ``columns`` (signal -> the channel's ``Name`` or
    ``SymbolName``; a channel named as a signal needs no entry), each converted from its
    ``Unit`` (none: the signal's SI unit); the time column of their group, in ms, becomes ``t``
    (s) from 0.

    Raises
    ------
    MeasuredDataError
        On a malformed export, channels the run needs that are missing or on different time
        columns, unknown units or non-numeric samples (lines named).
    """
    path = Path(path)
    lines = path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    separator = "\t" if any("\t" in line for line in lines[:40]) else ";"
    rows = [line.split(separator) for line in lines]
    blocks = _blocks(lines)
    if len(blocks) < 3:
        raise MeasuredDataError(
            f"{path}: not a TwinCAT Scope export: expected a header block, a blank line, the "
            "channel rows, a blank line and the samples"
        )
    channel_rows = {r[0].strip(): [c.strip() for c in r] for r in (rows[i] for i in blocks[1]) if r}
    if "Name" not in channel_rows:
        raise MeasuredDataError(f"{path}: the channel rows hold no 'Name' row")
    names = channel_rows["Name"]
    groups = [i for i, cell in enumerate(names) if cell == "Name"]
    channel_of: dict[str, int] = {}
    time_column: dict[int, int] = {}
    for index, start in enumerate(groups):
        stop = groups[index + 1] if index + 1 < len(groups) else len(names)
        for column in range(start + 1, stop):
            for key in ("Name", "SymbolName"):
                cells = channel_rows.get(key, [])
                if column < len(cells) and cells[column]:
                    channel_of.setdefault(cells[column], column)
            time_column[column] = start
    data = [rows[i] for i in range(blocks[2][0], len(rows)) if any(c.strip() for c in rows[i])]
    if data and data[-1][0].strip() == _TWINCAT_EOF:
        data = data[:-1]
    sample = [c for r in data[:20] for c in r if c.strip()]
    decimal_comma = separator != "," and any("," in c for c in sample)
    wanted = dict(columns or {})
    for signal in SIGNALS:
        if signal not in wanted and signal in channel_of:
            wanted[signal] = signal
    missing = {s: n for s, n in wanted.items() if n not in channel_of}
    if missing:
        raise MeasuredDataError(
            f"{path}: no channel named {sorted(missing.values())} (for {sorted(missing)}); the "
            f"export has {sorted(channel_of)}"
        )
    _checked_signals(path, dict.fromkeys([*wanted, "t"]), open_loop, sorted(channel_of))

    def column(index: int, label: str) -> np.ndarray:
        values = []
        for line, row in enumerate(data):
            try:
                values.append(_twincat_number(row[index], decimal_comma))
            except (ValueError, IndexError):
                raise MeasuredDataError(
                    f"{path}: channel {label!r}: sample {line + 1} is not a number"
                ) from None
        result = np.array(values)
        if not np.all(np.isfinite(result)):
            raise MeasuredDataError(f"{path}: channel {label!r} has missing or non-finite samples")
        return result

    clocks = sorted({time_column[channel_of[n]] for n in wanted.values()})
    milliseconds = column(clocks[0], "time")
    for clock in clocks[1:]:  # each channel its own time column: the same sample times
        if not np.allclose(column(clock, "time"), milliseconds, rtol=0.0, atol=1e-9):
            raise MeasuredDataError(
                f"{path}: the channels {sorted(wanted.values())} are sampled at different "
                "times; export them at one sample time"
            )
    signals = {"t": (milliseconds - milliseconds[0]) * 1e-3}
    units = {"t": "s"}
    unit_cells = channel_rows.get("Unit", [])
    for signal, name in wanted.items():
        index = channel_of[name]
        unit = _twincat_unit(unit_cells[index] if index < len(unit_cells) else "")
        header = f"{name} [{unit}]" if unit else name
        signals[signal], units[signal] = _converted(path, signal, header, column(index, name))
    run = MeasuredRun.from_signals(str(path), signals, units)
    check_time(run)
    return run


EMPS_SIGNALS = {"t": "t", "qg": "x_ref", "qm": "x", "vir": "current"}
EMPS_SCALARS = ("gtau", "kp", "kv")
# The columns of an HSM150 run's ``data`` array, as its README gives them.
HSM150_SIGNALS = (
    "t",
    "angle_ref",
    "motor_angle",
    "motor_speed",
    "input_torque",
    "measured_torque",
    "current",
)
HSM150_SCALARS = ("J", "B", "Mn", "Mmax", "N", "KFI", "Cu", "Tn", "Tvz", "Tgm", "Tsim")


def _numeric(path: Path, name: str, value: object) -> np.ndarray:
    """A .mat variable as a flat float64 array; MeasuredDataError naming it otherwise."""
    try:
        values = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        values = np.empty(0)
    if values.size == 0:
        raise MeasuredDataError(
            f"{path}: variable {name!r} is not numeric (got {np.asarray(value).dtype} data); "
            "expected numbers"
        )
    return values


def _load_mat(path: Path) -> dict:
    from scipy.io import loadmat

    try:
        return loadmat(str(path))
    except (OSError, ValueError, NotImplementedError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as a MATLAB file: {exc}") from exc


def read_emps_mat(path: Path | str) -> MeasuredRun:
    """Read an EMPS benchmark .mat file as it is published (with or without ``pulses_N``).

    Raises
    ------
    MeasuredDataError
        On an unreadable file, a missing variable, signals of different lengths or non-finite
        values.
    """
    path = Path(path)
    data = _load_mat(path)
    missing = [name for name in EMPS_SIGNALS if name not in data]
    if missing:
        raise MeasuredDataError(
            f"{path}: missing variable(s) {missing}; an EMPS file holds t, qg, qm, vir"
        )
    signals = {}
    for name, role in EMPS_SIGNALS.items():
        values = _numeric(path, name, data[name])
        if not np.all(np.isfinite(values)):
            raise MeasuredDataError(f"{path}: variable {name!r} has non-finite values")
        signals[role] = values
    if len({len(v) for v in signals.values()}) != 1:
        raise MeasuredDataError(f"{path}: t, qg, qm and vir must have the same length")
    scalars = {
        name: float(_numeric(path, name, data[name])[0]) for name in EMPS_SCALARS if name in data
    }
    if "pulses_N" in data:
        pulses = _numeric(path, "pulses_N", data["pulses_N"])
        if pulses.shape != signals["t"].shape or not np.all(np.isfinite(pulses)):
            raise MeasuredDataError(f"{path}: pulses_N must be finite and as long as t")
        signals["pulses_N"] = pulses
    run = MeasuredRun.from_signals(str(path), signals, {"current": "V", "pulses_N": "N"}, scalars)
    check_time(run)
    return run


def read_hsm150_mat(path: Path | str) -> MeasuredRun:
    """Read an HSM150 bench run (.mat, as published: ``data`` and the bench's scalars).

    Raises
    ------
    MeasuredDataError
        On an unreadable file, a ``data`` array that is not 7 numeric columns, non-finite values,
        or irregular time.
    """
    path = Path(path)
    data = _load_mat(path)
    array = np.asarray(data.get("data", np.empty((0, 0))))
    if array.ndim != 2 or array.shape[1] != len(HSM150_SIGNALS):
        raise MeasuredDataError(
            f"{path}: variable 'data' must be an array of {len(HSM150_SIGNALS)} columns "
            f"({', '.join(HSM150_SIGNALS)}), got shape {array.shape}"
        )
    values = _numeric(path, "data", array).reshape(array.shape)
    signals = {}
    for index, name in enumerate(HSM150_SIGNALS):
        if not np.all(np.isfinite(values[:, index])):
            raise MeasuredDataError(f"{path}: column {index + 1} of 'data' ({name}) is not finite")
        signals[name] = values[:, index]
    scalars = {
        name: float(_numeric(path, name, data[name])[0]) for name in HSM150_SCALARS if name in data
    }
    run = MeasuredRun.from_signals(str(path), signals, scalars=scalars)
    check_time(run)
    return run


def read_mat(path: Path | str) -> MeasuredRun:
    """A .mat run in the format its variables show: EMPS (``qg``, ``qm``, ``vir``) or HSM150
    (a ``data`` array)."""
    path = Path(path)
    from scipy.io import whosmat

    try:
        names = {name for name, _, _ in whosmat(str(path))}
    except (OSError, ValueError, NotImplementedError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as a MATLAB file: {exc}") from exc
    if "data" in names and not {"qg", "qm"} & names:
        return read_hsm150_mat(path)
    return read_emps_mat(path)


def read_measured(
    path: Path | str, columns: Mapping[str, str] | None = None, open_loop: bool = False
) -> MeasuredRun:
    """Read a measured run: .csv (the project's format with units and a column map ``columns``,
    or a TwinCAT Scope export) or .mat (EMPS benchmark, HSM150 bench). ``open_loop``: the run
    drove its plant open loop (a position and the motor speed, no reference or command needed).
    """
    path = Path(path)
    if not path.is_file():
        raise MeasuredDataError(f"{path}: file not found")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        return read_measured_csv(path, columns, open_loop)
    if suffix == ".mat":
        return read_mat(path)
    raise MeasuredDataError(
        f"{path}: unknown measured-run type {path.suffix!r}; expected .csv or .mat"
    )


def check_time(run: MeasuredRun) -> None:
    """Strictly increasing, regular time with enough samples; MeasuredDataError otherwise."""
    t = run.t
    if len(t) < MIN_SAMPLES:
        raise MeasuredDataError(
            f"{run.source}: only {len(t)} samples; at least {MIN_SAMPLES} needed"
        )
    steps = np.diff(t)
    if np.any(steps <= 0):
        first = int(np.flatnonzero(steps <= 0)[0])
        raise MeasuredDataError(
            f"{run.source}: column 't' must increase strictly; t[{first + 1}] = {t[first + 1]} s "
            f"follows t[{first}] = {t[first]} s"
        )
    period = run.period
    jitter = np.abs(steps - period).max() / period
    if jitter > REGULARITY_TOLERANCE:
        where = int(np.argmax(np.abs(steps - period)))
        raise MeasuredDataError(
            f"{run.source}: column 't' is irregular: step {steps[where]:.6g} s at "
            f"t = {t[where]:.6g} s "
            f"against a mean period of {period:.6g} s (gaps or jitter; resample to a regular grid)"
        )


def _scale_mismatch(measured: np.ndarray, expected: np.ndarray) -> str | None:
    span = np.ptp(expected)
    if span == 0:
        return None
    ratio = np.ptp(measured) / span
    for factor, meaning in UNIT_FACTORS.items():
        if abs(ratio / factor - 1) < 0.05:
            return meaning
    return None


def check_against_reference(run: MeasuredRun, reference: ReferenceGrid) -> None:
    """The run must follow the scenario's reference (same motion, units of m, within its time).

    Raises
    ------
    MeasuredDataError
        When ``x_ref`` or ``x`` looks scaled by 1000 (mm instead of m), the run lasts longer
        or shorter than the reference (within two samples), or ``x_ref`` differs from the
        scenario's reference.
    """
    if run.t[-1] > reference.duration + 2 * run.period or run.t[0] < -run.period:
        raise MeasuredDataError(
            f"{run.source}: the run spans {run.t[0]:.4g} to {run.t[-1]:.4g} s, outside the "
            f"scenario's reference (0 to {reference.duration:.4g} s)"
        )
    if run.t[-1] < reference.duration - 2 * run.period or run.t[0] > run.period:
        raise MeasuredDataError(
            f"{run.source}: the run spans {run.t[0]:.4g} to {run.t[-1]:.4g} s, shorter than "
            f"the scenario's reference (0 to {reference.duration:.4g} s): a run cut short "
            "leaves out motion the scenario needs; record the whole reference"
        )
    expected = np.interp(run.t, reference.time, reference.position)
    for column, values in (("x_ref", run.x_ref), ("x", run.x)):
        meaning = _scale_mismatch(values, expected)
        if meaning:
            raise MeasuredDataError(
                f"{run.source}: column {column!r} looks like {meaning} (its range is "
                f"{np.ptp(values):.4g} against the scenario's {np.ptp(expected):.4g} m)"
            )
    tolerance = 1e-6 + 1e-3 * np.ptp(expected)  # m
    deviation = np.abs(run.x_ref - expected)
    if deviation.max() > tolerance:
        at = int(np.argmax(deviation))
        raise MeasuredDataError(
            f"{run.source}: column 'x_ref' does not match the scenario's reference: "
            f"{deviation[at] * 1e6:.4g} um apart at t = {run.t[at]:.4g} s (tolerance "
            f"{tolerance * 1e6:.3g} um); is it a run of another scenario?"
        )


def current_warnings(run: MeasuredRun, current_limit: float) -> list[str]:
    """Warnings about the current column (A): mA instead of A, or saturation."""
    found = []
    peak = float(np.abs(run.current).max())
    if peak > 50 * current_limit:
        found.append(
            f"{run.source}: 'current' peaks at {peak:.4g}, 50x the current limit "
            f"{current_limit} A: is it in mA?"
        )
    saturated = float(np.mean(np.abs(run.current) >= 0.999 * current_limit))
    if saturated > 0.01:
        found.append(f"{run.source}: the current is at its limit in {saturated:.1%} of the samples")
    return found
