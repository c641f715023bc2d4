"""What the commands of ``twin`` write for the user: JSON and CSV files, warnings on stderr."""

from __future__ import annotations

import json
import os
import shlex
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2) + "\n")


def write_summary(path: Path, summary: dict[str, Any], as_json: bool) -> bool:
    """Write a command's summary as indented JSON and, with ``--json``, print it on one line.

    Returns
    -------
    bool
        True when the command prints its text instead (no ``--json``).
    """
    write_json(path, summary)
    if as_json:
        print(json.dumps(summary))
    return not as_json


FORK_FROM_ROWS = 10_000  # a record this long is formatted in two processes (a fork costs ~5 ms)


def write_record_csv(path: Path, record: RunRecord | pd.DataFrame) -> None:
    """Write a run record (float columns) as CSV: the bytes of pandas' ``to_csv(path,
    index=False)`` of the record in about a quarter of the time.

    Each value is written as Python writes a float (the shortest text that reads back the same
    number; pandas writes the same), a NaN as an empty field (left to pandas). Formatting the
    floats is most of the time: a forked child formats the second half of the rows while this
    process formats the first (where ``os.fork`` exists). The file appears complete or not at
    all (written under a temporary name, then renamed).
    """
    import numpy as np  # not at start (twin --help)

    values = record.to_numpy()
    kinds = getattr(record, "dtypes", [values.dtype])  # a DataFrame's columns may be integers
    if any(kind != np.float64 for kind in kinds) or np.isnan(values).any():
        frame = record.frame() if hasattr(record, "frame") else record
        frame.to_csv(path, index=False)
        return
    header = ",".join(str(name) for name in record.columns) + "\n"
    split = hasattr(os, "fork") and len(values) >= FORK_FROM_ROWS
    half = len(values) // 2 if split else len(values)
    temporary = path.with_name(f".{path.name}.{os.getpid()}")
    second = temporary.with_suffix(".second")
    child = _format_in_child(values[half:], second) if half < len(values) else None
    try:
        text = header + _csv_rows(values[:half])
        if child is not None:
            _, status = os.waitpid(child, 0)
            child = None
            if status != 0:
                raise OSError(f"{path}: the process formatting its second half failed")
            text += second.read_text()
        temporary.write_text(text)
        os.replace(temporary, path)
    finally:
        if child is not None:  # interrupted while the child formats: stop it
            os.kill(child, signal.SIGKILL)
            os.waitpid(child, 0)
        temporary.unlink(missing_ok=True)
        second.unlink(missing_ok=True)


def _csv_rows(values: np.ndarray) -> str:
    """CSV lines of float rows, each value as Python's repr (shortest round trip)."""
    line = ",".join(["%r"] * values.shape[1]) + "\n"
    return "".join([line % tuple(row) for row in values.tolist()])


def _format_in_child(values: np.ndarray, path: Path) -> int:
    """Fork a child that writes :func:`_csv_rows` of ``values`` to ``path`` and exits (0 when
    written, 1 otherwise) without running this process's exit handlers; its pid."""
    child = os.fork()
    if child == 0:  # pragma: no cover - the child's exit code is what the parent checks
        code = 1
        try:
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            path.write_text(_csv_rows(values))
            code = 0
        finally:
            os._exit(code)
    return child


def command_line(name: str) -> str:
    """The command line of ``twin NAME`` as typed (when this process is that command), for the
    files that say what made them; ``twin NAME`` otherwise."""
    if len(sys.argv) > 1 and sys.argv[1] == name:
        return shlex.join(["twin", *sys.argv[1:]])
    return f"twin {name}"


def warn_plant_mismatch(scenario: Scenario, fmu: Path | None) -> list[str]:
    """Warn on stderr when ``--plant`` is another model than the scenario's; the warnings."""
    from twin_cosim.scenario import plant_mismatch  # heavy: not at start (twin --help)

    warning = None if fmu is None else plant_mismatch(scenario, fmu)
    if warning is None:
        return []
    print(f"twin: warning: {warning}", file=sys.stderr)
    return [warning]
