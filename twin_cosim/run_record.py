"""One run's samples as named columns over a single float64 array: what a run needs to be
measured, checked, written and drawn, without importing pandas (a fifth of a second at start)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd


class RunRecord:
    """Rows of samples, named columns; ``record["x"]`` is the column as a numpy view.

    Parameters
    ----------
    values
        One row per sample, one column per name (float64; each column in its own unit, as the
        producer documents, e.g. :data:`twin_cosim.cosim.RECORD_COLUMNS`).
    columns
        The column names, in order.
    """

    def __init__(self, values: np.ndarray, columns: Sequence[str]) -> None:
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != len(columns):
            raise ValueError(f"a record needs {len(columns)} columns, got shape {values.shape}")
        self._values = values
        self.columns = list(columns)
        self._index = {name: i for i, name in enumerate(self.columns)}

    def __getitem__(self, column: str) -> np.ndarray:
        """The column ``column`` (a view: writing to it changes the record)."""
        try:
            return self._values[:, self._index[column]]
        except KeyError:
            raise KeyError(f"no column {column!r}; the record has {self.columns}") from None

    def __setitem__(self, column: str, values: np.ndarray | float) -> None:
        """Write ``values`` into the column ``column`` (``record["current"] += offset`` works)."""
        self[column][:] = values

    def __len__(self) -> int:
        return self._values.shape[0]

    def to_numpy(self) -> np.ndarray:
        """The samples, one row each (the record's own array)."""
        return self._values

    def frame(self) -> pd.DataFrame:
        """The record as a pandas DataFrame (the same columns and values)."""
        import pandas as pd

        return pd.DataFrame(self._values, columns=self.columns)
