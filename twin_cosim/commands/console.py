"""What the commands of ``twin`` write for the user: JSON and CSV files, warnings on stderr."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

    from twin_cosim.scenario import Scenario


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2) + "\n")


def write_record_csv(path: Path, record: pd.DataFrame) -> None:
    """Write a run record (float columns) as CSV: the bytes of ``record.to_csv(path,
    index=False)`` in about half the time.

    Each value is written as Python writes a float (the shortest text that reads back the same
    number; pandas writes the same), a NaN as an empty field (left to pandas).
    """
    import numpy as np  # not at start (twin --help)

    values = record.to_numpy()
    if any(kind != np.float64 for kind in record.dtypes) or np.isnan(values).any():
        record.to_csv(path, index=False)
        return
    line = ",".join(["%r"] * values.shape[1]) + "\n"
    header = ",".join(str(name) for name in record.columns) + "\n"
    path.write_text(header + "".join([line % tuple(row) for row in values.tolist()]))


def warn_plant_mismatch(scenario: Scenario, fmu: Path | None) -> list[str]:
    """Warn on stderr when ``--plant`` is another model than the scenario's; the warnings."""
    from twin_cosim.scenario import plant_mismatch  # heavy: not at start (twin --help)

    warning = None if fmu is None else plant_mismatch(scenario, fmu)
    if warning is None:
        return []
    print(f"twin: warning: {warning}", file=sys.stderr)
    return [warning]
