"""A run record: named views of one array, and the same table as a DataFrame."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.run_record import RunRecord


def test_columns_are_views_written_through_and_the_frame_holds_the_same():
    values = np.arange(6.0).reshape(3, 2)
    record = RunRecord(values, ["t", "current"])
    record["current"] += 10.0
    assert record.to_numpy()[:, 1].tolist() == [11.0, 13.0, 15.0]
    assert np.shares_memory(record["t"], record.to_numpy()) and len(record) == 3
    frame = record.frame()
    assert list(frame.columns) == ["t", "current"]
    assert np.array_equal(frame.to_numpy(), record.to_numpy())


def test_a_wrong_shape_or_column_is_named():
    with pytest.raises(ValueError, match="2 columns"):
        RunRecord(np.zeros((3, 3)), ["t", "x"])
    with pytest.raises(KeyError, match="no column 'x'"):
        RunRecord(np.zeros((3, 1)), ["t"])["x"]


def test_units_rows_and_added_columns_keep_names_and_units():
    record = RunRecord.from_columns(
        {"t": np.array([0.0, 1.0, 2.0]), "x": np.array([1.0, 2.0, 3.0])}, {"t": "s", "x": "m"}
    )
    assert record.units == {"t": "s", "x": "m"} and "x" in record and "y" not in record
    later = record.rows(record["t"] > 0.5)
    assert later["x"].tolist() == [2.0, 3.0] and later.units["x"] == "m"
    wider = record.with_columns({"v": np.array([1.0, 1.0, 1.0])}, {"v": "m/s"})
    assert wider.columns == ["t", "x", "v"] and wider.units["v"] == "m/s"
    assert record.get("v") is None and list(record.select(["x"])) == ["x"]


def test_units_of_unknown_columns_ragged_columns_and_repeated_names_are_refused():
    with pytest.raises(ValueError, match="does not have"):
        RunRecord(np.zeros((2, 1)), ["t"], {"x": "m"})
    with pytest.raises(ValueError, match="one length"):
        RunRecord.from_columns({"t": np.zeros(2), "x": np.zeros(3)})
    with pytest.raises(ValueError, match="must differ"):
        RunRecord(np.zeros((2, 2)), ["t", "t"])
