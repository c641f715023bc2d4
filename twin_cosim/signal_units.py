"""Units of measured signals: the units a file may carry, what each measures and its factor to
the SI unit the twin computes in.

A measured file says the unit of a column in its header (``x [mm]``, ``current (mA)``) or in a
drive trace's metadata (TwinCAT Scope's ``Unit`` row); :func:`to_si` converts the values. Each
signal of a run measures one quantity (:data:`QUANTITY_OF`: ``x`` a length, ``motor_speed`` an
angular speed, ...), so that a unit of another quantity (``x [rpm]``) is refused rather than
guessed, as is a unit this table does not know. A column without a unit is in the signal's SI
unit (:data:`SI_UNIT`), the documented default of the project's CSV format.
"""

from __future__ import annotations

import math
import re

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
