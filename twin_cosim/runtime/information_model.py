"""The OPC UA information model of a machine that publishes trace windows, and the window it
carries: the one place of its names, shared by the virtual machine's server and the twin's client.

The model (docs/runtime.md), every browse name in the namespace :data:`MACHINE_NAMESPACE`::

    Objects
      Machine                      object (a machine tool, as OPC UA for Machine Tools names it)
        <axis>                     object, named as the scenario's axis (X for a single axis)
          Trace                    object: one window of the drive's trace
            time                   Double[]  s
            position_reference     Double[]  m
            position               Double[]  m
            current                Double[]  A
            motor_speed            Double[]  rad/s (optional)
            Sequence               UInt32: incremented after a window's arrays are all written

The arrays of a window are sampled at the position-loop period. A client finds the namespace
index from its URI, browses by these names, subscribes to ``Sequence`` and reads the arrays when
it changes.

The twin writes what it finds into a namespace of its own, :data:`TWIN_NAMESPACE`, when the
server offers it and allows writing::

    Objects
      Twin                         object
        Window                     UInt32: the last window the twin checked (its Sequence)
        Gap                        Double: that window's normalised RMS gap (1: the noise floor)
        Alarms                     UInt32: alarms raised so far
        Alarm                      String: the last alarm, as its JSON line of the log
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MACHINE_NAMESPACE = "urn:twin-cosim:machine"
TWIN_NAMESPACE = "urn:twin-cosim:twin"
MACHINE = "Machine"
TRACE = "Trace"
SEQUENCE = "Sequence"
SINGLE_AXIS = "X"  # the axis of a single-axis scenario
# The arrays of a window: browse name -> unit; motor_speed may be missing.
ARRAYS = {
    "time": "s",
    "position_reference": "m",
    "position": "m",
    "current": "A",
    "motor_speed": "rad/s",
}
REQUIRED_ARRAYS = ("time", "position_reference", "position", "current")
OPTIONAL_ARRAYS = ("motor_speed",)
TWIN = "Twin"
TWIN_VARIABLES = {"Window": "UInt32", "Gap": "Double", "Alarms": "UInt32", "Alarm": "String"}
SEQUENCE_MODULUS = 2**32  # Sequence is a UInt32: it wraps to 0 after 2^32 - 1
PERIOD_TOLERANCE = 1e-6  # relative: a window's sample period against the position loop's


class WindowError(ValueError):
    """A window that cannot be checked (its message names the window and what is wrong)."""


@dataclass(frozen=True)
class Window:
    """One trace window of an axis as the machine published it.

    Attributes
    ----------
    sequence : int
        The server's ``Sequence`` after the window was written.
    time : numpy.ndarray
        Sample times, s (any origin; the window's own clock).
    position_reference : numpy.ndarray
        The position reference of the window, m.
    position : numpy.ndarray
        The measured carriage position, m.
    current : numpy.ndarray
        The current command, A.
    motor_speed : numpy.ndarray or None
        The measured motor speed, rad/s, when the server publishes it.
    """

    sequence: int
    time: np.ndarray
    position_reference: np.ndarray
    position: np.ndarray
    current: np.ndarray
    motor_speed: np.ndarray | None = None

    @property
    def samples(self) -> int:
        """Number of samples."""
        return len(self.time)

    @property
    def period(self) -> float:
        """Sample period, s."""
        return float((self.time[-1] - self.time[0]) / (len(self.time) - 1))

    @property
    def duration(self) -> float:
        """Time the window covers, s (samples times the period)."""
        return self.samples * self.period

    def arrays(self) -> dict[str, np.ndarray]:
        """The window's arrays by browse name (``motor_speed`` only when present)."""
        named = {name: getattr(self, name) for name in REQUIRED_ARRAYS}
        if self.motor_speed is not None:
            named["motor_speed"] = self.motor_speed
        return named


def window_of(sequence: int, arrays: dict[str, object], label: str) -> Window:
    """A checked window from the arrays read off the server.

    Parameters
    ----------
    sequence
        The window's ``Sequence``.
    arrays
        Browse name -> values read (lists of numbers); ``motor_speed`` may be missing or empty.
    label
        How messages name the window (e.g. ``window 12 (Sequence 13)``).

    Raises
    ------
    WindowError
        A required array missing or not numeric, arrays of unequal length, fewer than 8
        samples, a value that is NaN or infinite, or time not increasing at a regular step.
    """
    values: dict[str, np.ndarray] = {}
    for name in ARRAYS:
        raw = arrays.get(name)
        if raw is None or (name in OPTIONAL_ARRAYS and len(raw) == 0):  # type: ignore[arg-type]
            if name in REQUIRED_ARRAYS:
                raise WindowError(f"{label}: no array {name!r}")
            continue
        try:
            values[name] = np.asarray(raw, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise WindowError(f"{label}: array {name!r} is not a Double array") from None
    lengths = {name: len(v) for name, v in values.items()}
    if len(set(lengths.values())) != 1:
        raise WindowError(f"{label}: arrays of unequal length {lengths}")
    if lengths["time"] < 8:
        raise WindowError(f"{label}: {lengths['time']} samples; a window needs at least 8")
    for name, v in values.items():
        bad = np.flatnonzero(~np.isfinite(v))
        if len(bad):
            raise WindowError(
                f"{label}: {name} holds {len(bad)} NaN or infinite values (first at sample "
                f"{bad[0]})"
            )
    steps = np.diff(values["time"])
    step = float(np.median(steps))
    if step <= 0 or np.max(np.abs(steps - step)) > 1e-3 * step:
        raise WindowError(f"{label}: time must increase at a regular step")
    return Window(
        sequence,
        values["time"],
        values["position_reference"],
        values["position"],
        values["current"],
        values.get("motor_speed"),
    )


def check_period(window: Window, loop_period: float, label: str) -> None:
    """Refuse a window not sampled at the scenario's position-loop period (s)."""
    if not math.isclose(window.period, loop_period, rel_tol=PERIOD_TOLERANCE):
        raise WindowError(
            f"{label}: sampled every {window.period * 1e6:.6g} us; the scenario's position loop "
            f"runs every {loop_period * 1e6:.6g} us (windows must be sampled at the "
            "position-loop period)"
        )


def sequence_gap(previous: int, current: int) -> int:
    """Windows missed between two Sequence values read one after the other (UInt32, wrapping);
    0 when ``current`` follows ``previous``."""
    return (current - previous - 1) % SEQUENCE_MODULUS
