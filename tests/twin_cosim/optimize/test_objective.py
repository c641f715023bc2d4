"""The objective: E_pk for valid runs; penalties with reasons for violations and failures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin_cosim.cosim import run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.objective import Objective, ObjectiveSpec
from twin_cosim.paper import TABLE3
from twin_cosim.scenario import load_scenario

REFERENCE1 = str(Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml")


@pytest.fixture(scope="module")
def objective():
    instance = Objective(ObjectiveSpec(REFERENCE1, None, iau_limit=None))
    yield instance
    instance.close()


def test_valid_candidate_scores_its_epk(objective, plant):
    result = objective(TABLE3["ga"].as_array())
    record = run_scenario(plant, load_scenario(REFERENCE1), TABLE3["ga"])
    assert result["status"] == "ok"
    assert result["fitness"] == compute_metrics(record).E_pk_um


def test_iau_cap_violation_is_penalised(objective):
    spec = ObjectiveSpec(REFERENCE1, None, iau_limit=1.0)  # A.s, far below what the run needs
    capped = Objective(spec)
    result = capped(TABLE3["ft"].as_array())
    capped.close()
    assert result["status"] == "violation"
    assert "above the cap" in result["reason"]
    assert result["fitness"] == pytest.approx(1e6 + result["metrics"]["E_pk_um"])


def test_unstable_candidate_is_stopped_and_penalised(objective):
    # A position gain far beyond the speed loop's bandwidth: the error runs away.
    result = objective(np.array([20000.0, 0.05, 0.0, 0.0, 0.01, 0.1]))
    assert result["status"] == "unstable"
    assert "exceeded 1000 um" in result["reason"]
    assert result["fitness"] == 2e6
    assert result["metrics"] is None


def test_refused_parameters_are_a_failure(objective):
    result = objective(np.array([66.0, 0.3, 0.008, 0.7, 0.0, 0.1]))  # PP3 = 0
    assert result["status"] == "failed"
    assert "PP3 must be > 0" in result["reason"]
