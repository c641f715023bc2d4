"""One run's samples as named columns with units over a single float64 array: the one record type
inside the package (the twin's runs, measured runs, contour records), without importing pandas
(a fifth of a second at start). pandas appears only where files are read and written and
plots drawn (:meth:`RunRecord.frame`)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd


class RunRecord:
    """Rows of samples, named columns, a unit per column; ``record["x"]`` is the column as a
    numpy view.

    Parameters
    ----------
    values
        One row per sample, one column per name (float64; each column in its own unit).
    columns
        The column names, in order.
    units
        The unit of each column (``"s"``, ``"m"``, ``"A"``, ``"rad/s"``, ``"1"`` for a pure
        number), by name; a column not named here has the unit ``""`` (not declared).
    """

    def __init__(
        self,
        values: np.ndarray,
        columns: Sequence[str],
        units: Mapping[str, str] | None = None,
    ) -> None:
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] != len(columns):
            raise ValueError(f"a record needs {len(columns)} columns, got shape {values.shape}")
        if len(set(columns)) != len(columns):
            raise ValueError(f"a record's column names must differ: {list(columns)}")
        self._values = values
        self.columns = list(columns)
        self._index = {name: i for i, name in enumerate(self.columns)}
        units = dict(units or {})
        unknown = sorted(set(units) - set(self._index))
        if unknown:
            raise ValueError(f"units given for columns the record does not have: {unknown}")
        self.units = {name: units.get(name, "") for name in self.columns}

    @classmethod
    def from_columns(
        cls, columns: Mapping[str, np.ndarray], units: Mapping[str, str] | None = None
    ) -> RunRecord:
        """A record from equal-length columns by name (copied into one array), in their order."""
        names = list(columns)
        arrays = [np.asarray(columns[name], dtype=np.float64) for name in names]
        lengths = {a.shape for a in arrays}
        if len(lengths) > 1 or any(a.ndim != 1 for a in arrays):
            shapes = {name: a.shape for name, a in zip(names, arrays, strict=True)}
            raise ValueError(f"a record's columns must be 1-D of one length, got {shapes}")
        values = np.column_stack(arrays) if arrays else np.empty((0, 0))
        return cls(values, names, {n: u for n, u in (units or {}).items() if n in columns})

    def __getitem__(self, column: str) -> np.ndarray:
        """The column ``column`` (a view: writing to it changes the record)."""
        try:
            return self._values[:, self._index[column]]
        except KeyError:
            raise KeyError(f"no column {column!r}; the record has {self.columns}") from None

    def __setitem__(self, column: str, values: np.ndarray | float) -> None:
        """Write ``values`` into the column ``column`` (``record["current"] += offset`` works)."""
        self[column][:] = values

    def __contains__(self, column: object) -> bool:
        return column in self._index

    def __iter__(self) -> Iterator[str]:
        """The column names, as a mapping's keys."""
        return iter(self.columns)

    def __len__(self) -> int:
        return self._values.shape[0]

    def get(self, column: str) -> np.ndarray | None:
        """The column ``column``, or None when the record has none of that name."""
        return self[column] if column in self._index else None

    def rows(self, selection: slice | np.ndarray) -> RunRecord:
        """The rows picked by a slice, a boolean mask or indices (a new record, same columns)."""
        return RunRecord(self._values[selection], self.columns, self.units)

    def with_columns(
        self, columns: Mapping[str, np.ndarray], units: Mapping[str, str] | None = None
    ) -> RunRecord:
        """A new record with ``columns`` added (or replaced, by name), one value per row."""
        merged = {name: self[name] for name in self.columns}
        merged.update(columns)
        return RunRecord.from_columns(merged, {**self.units, **(units or {})})

    def select(self, columns: Sequence[str]) -> RunRecord:
        """A new record of the named columns only, in that order."""
        return RunRecord.from_columns({n: self[n] for n in columns}, self.units)

    def copy(self) -> RunRecord:
        """A record with its own copy of the samples."""
        return RunRecord(self._values.copy(), self.columns, self.units)

    def to_numpy(self) -> np.ndarray:
        """The samples, one row each (the record's own array)."""
        return self._values

    def frame(self) -> pd.DataFrame:
        """The record as a pandas DataFrame (the same columns and values), for files and plots."""
        import pandas as pd

        return pd.DataFrame(self._values, columns=self.columns)
