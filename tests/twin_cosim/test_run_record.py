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
