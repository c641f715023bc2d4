"""Readers of measured runs by file type: the project's CSV format (and, for the EMPS benchmark,
its .mat files)."""

from __future__ import annotations

from pathlib import Path

from twin_cosim.gap.measured import MeasuredDataError, MeasuredRun, read_measured_csv
from twin_cosim.scenario import Scenario


def read_measured(path: Path | str, scenario: Scenario) -> MeasuredRun:
    """Read a measured run; the file type decides the reader.

    Raises
    ------
    MeasuredDataError
        On an unknown file type or bad contents.
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return read_measured_csv(path)
    raise MeasuredDataError(f"{path}: unknown measured-run type {path.suffix!r}; expected .csv")
