"""Measured-run CSVs: every defect gets an error naming the file and the column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin_cosim.measured import (
    MeasuredDataError,
    check_against_reference,
    current_warnings,
    read_emps_mat,
    read_measured_csv,
)
from twin_cosim.scenario import load_scenario

REFERENCE1 = Path(__file__).resolve().parents[2] / "scenarios" / "reference1.yaml"


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(REFERENCE1)


def good_frame(scenario) -> pd.DataFrame:
    grid = scenario.reference
    return pd.DataFrame(
        {
            "t": grid.time,
            "x_ref": grid.position,
            "x": grid.position + 1e-7,
            "current": np.zeros(len(grid.time)),
            "extra": 1.0,
        }
    )


def write(tmp_path, frame: pd.DataFrame) -> Path:
    path = tmp_path / "run.csv"
    frame.to_csv(path, index=False)
    return path


def test_good_run_loads_and_matches(tmp_path, scenario):
    run = read_measured_csv(write(tmp_path, good_frame(scenario)))
    check_against_reference(run, scenario.reference)
    assert run.period == pytest.approx(250e-6)
    assert run.motor_speed is None


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: f.drop(columns="current"), r"missing column\(s\) \['current'\]"),
        (lambda f: f.assign(x=f["x"].where(f.index != 10)), "column 'x' has 1 missing"),
        (
            lambda f: f.assign(t=f["t"].where(f.index != 50, f["t"][48])),
            "'t' must increase strictly",
        ),
        (lambda f: f.drop(index=range(100, 110)), "'t' is irregular"),
    ],
)
def test_defects_are_named(tmp_path, scenario, change, message):
    with pytest.raises(MeasuredDataError, match=message) as info:
        read_measured_csv(write(tmp_path, change(good_frame(scenario))))
    assert "run.csv" in str(info.value)


@pytest.mark.parametrize(
    ("column", "meaning"), [("x_ref", "mm instead of m"), ("x", "mm instead of m")]
)
def test_units_off_by_1000(tmp_path, scenario, column, meaning):
    frame = good_frame(scenario)
    frame[column] *= 1000.0
    run = read_measured_csv(write(tmp_path, frame))
    with pytest.raises(MeasuredDataError, match=f"'{column}' looks like {meaning}"):
        check_against_reference(run, scenario.reference)


def test_run_of_another_scenario(tmp_path, scenario):
    frame = good_frame(scenario)
    frame["x_ref"] = frame["x_ref"][::-1].to_numpy()
    run = read_measured_csv(write(tmp_path, frame))
    with pytest.raises(MeasuredDataError, match="does not match the scenario's reference"):
        check_against_reference(run, scenario.reference)


def test_a_run_shorter_than_its_scenario_is_refused(tmp_path, scenario):
    """The issue's case: the first part of a run (a cut CSV) leaves out motion the scenario
    needs; the error names the file, its span and the span needed."""
    frame = good_frame(scenario)
    cut = frame[frame["t"] <= 0.53]
    run = read_measured_csv(write(tmp_path, cut))
    with pytest.raises(MeasuredDataError, match="shorter than the scenario's reference") as info:
        check_against_reference(run, scenario.reference)
    message = str(info.value)
    assert "run.csv" in message and "0 to 0.53 s" in message
    assert f"(0 to {scenario.reference.duration:.4g} s)" in message


def test_simulate_on_a_cut_run_is_refused_naming_the_file(tmp_path, scenario, capsys):
    from twin_cosim.cli import main

    cut = good_frame(scenario).drop(columns="extra")
    path = write(tmp_path, cut[cut["t"] <= 0.53])
    status = main(
        [
            "simulate",
            str(REFERENCE1),
            "--machine",
            str(path),
            "--no-plots",
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert status == 2
    assert f"{path}: the run spans 0 to 0.53 s, shorter" in capsys.readouterr().err


def test_current_in_milliamps_warns(tmp_path, scenario):
    frame = good_frame(scenario)
    frame["current"] = 1500.0 * np.sin(frame["t"])
    run = read_measured_csv(write(tmp_path, frame))
    assert any("is it in mA" in w for w in current_warnings(run, 20.0))


def test_mat_with_string_signals_is_named(tmp_path):
    from scipy.io import savemat

    path = tmp_path / "strings.mat"
    n = 200
    savemat(
        path, {"t": np.arange(n) * 1e-3, "qg": ["abc"] * n, "qm": np.zeros(n), "vir": np.zeros(n)}
    )
    with pytest.raises(MeasuredDataError, match=r"strings.mat: variable 'qg' is not numeric"):
        read_emps_mat(path)
