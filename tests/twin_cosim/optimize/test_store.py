"""A campaign's folder: the evaluation log keeps every completed evaluation and survives a torn
last line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from twin_cosim.optimize.store import EvaluationLog, candidate_key


def test_append_reload_and_lookup(tmp_path):
    path = tmp_path / "evaluations.jsonl"
    log = EvaluationLog(path)
    x = np.array([1.0, 0.1 + 0.2, 3.0])
    log.append(x, {"fitness": 2.5, "status": "ok"}, generation=0)
    log.close()
    again = EvaluationLog(path)
    assert again.lookup(x)["fitness"] == 2.5
    assert again.lookup(np.array([1.0, 0.3, 3.0])) is None  # 0.1 + 0.2 != 0.3: exact bits
    again.close()


def test_torn_last_line_is_dropped(tmp_path):
    path = tmp_path / "evaluations.jsonl"
    whole = json.dumps({"key": candidate_key(np.ones(2)), "x": [1.0, 1.0], "fitness": 1.0})
    path.write_text(whole + "\n" + whole[: len(whole) // 2])
    log = EvaluationLog(path)
    assert len(log) == 1
    log.append(np.zeros(2), {"fitness": 0.0}, generation=1)
    log.close()
    assert len(path.read_text().splitlines()) == 2


def test_corrupt_middle_line_is_an_error(tmp_path):
    path = tmp_path / "evaluations.jsonl"
    path.write_text("{broken\n{}\n")
    with pytest.raises(ValueError, match="corrupt line"):
        EvaluationLog(path)
