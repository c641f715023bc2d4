"""The log of ``twin watch``: ``DIR/windows.jsonl``, one JSON object a line, for people and other
tools, and the numbers of it as people read them.

A window is ``{"window": N, "sequence": S, "real_time_factor": R, ...}`` (N counted from 0 in the
order received, S the server's Sequence); every other line is an event,
``{"event": KIND, ...}``: ``connected``, ``lost``, ``restored``, ``restarted``, ``missed``,
``skipped``, ``baseline``, ``alarm``, ``diagnosis``, ``twin_namespace`` and the last line
``end``. Each line is written whole and flushed, so that the log read at any time (or after a
signal) is complete up to its last line. docs/runtime.md lists every key.
"""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.gap.verdict import number

LOG_NAME = "windows.jsonl"
# How people read a tracked value: unit -> (factor, unit shown).
READABLE = {"N.m": (1e3, "mN.m"), "m": (1e6, "um"), "1": (100.0, "%"), "s": (1e3, "ms")}


def plain(value: Any) -> Any:
    """``value`` as JSON holds it: numpy numbers as Python numbers, non-finite floats as None,
    tuples as lists."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class WindowLog:
    """The JSONL log, written whole line by line (from any thread)."""

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._file = path.open("w", encoding="utf-8")
        self._lock = threading.Lock()

    def write(self, entry: dict[str, Any]) -> None:
        """Append one object as a line and flush it."""
        line = json.dumps(plain(entry), separators=(",", ":")) + "\n"
        with self._lock:
            if not self._file.closed:
                self._file.write(line)
                self._file.flush()

    def close(self) -> None:
        """Close the file (later writes are dropped)."""
        with self._lock:
            self._file.close()


def read_log(path: Path) -> list[dict[str, Any]]:
    """The objects of a log, in order.

    Raises
    ------
    ValueError
        Naming the file and line of a line that is not a JSON object.
    """
    entries = []
    with path.open(encoding="utf-8") as file:
        for number, line in enumerate(file, start=1):
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ValueError(f"{path}:{number}: not a JSON object ({exc.msg})") from None
            if not isinstance(entry, dict):
                raise ValueError(f"{path}:{number}: not a JSON object")
            entries.append(entry)
    return entries


def readable(value: float, unit: str) -> tuple[float, str]:
    """A value in the unit people read it in (mN.m, um, %)."""
    factor, shown = READABLE.get(unit, (1.0, unit))
    return value * factor, shown


def quantity(value: float, unit: str, signed: bool = False) -> str:
    """``+3.13 mN.m``: a value with its readable unit."""
    shown, text = readable(value, unit)
    sign = "+" if signed and shown > 0 else ""
    return f"{sign}{number(shown)} {text}".strip()
