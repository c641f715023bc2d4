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
    parse_columns,
    position_label,
    read_emps_mat,
    read_measured,
    read_measured_csv,
)
from twin_cosim.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
REFERENCE1 = ROOT / "scenarios" / "reference1.yaml"
TWINCAT_EXAMPLE = ROOT / "docs" / "examples" / "twincat_scope_export.csv"


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


def with_speed(frame: pd.DataFrame) -> pd.DataFrame:
    """The good run with a motor speed (rad/s) and a current that moves (A)."""
    t = frame["t"].to_numpy()
    return frame.assign(motor_speed=30.0 * np.sin(7.0 * t), current=0.8 * np.cos(5.0 * t))


def in_other_units(frame: pd.DataFrame) -> pd.DataFrame:
    """The same run in ms, mm, um, mA and rpm, each unit in its column's header."""
    return pd.DataFrame(
        {
            "t [ms]": frame["t"] * 1e3,
            "x_ref (mm)": frame["x_ref"] * 1e3,
            "x [um]": frame["x"] * 1e6,
            "current [mA]": frame["current"] * 1e3,
            "motor_speed [rpm]": frame["motor_speed"] * 60.0 / (2.0 * np.pi),
        }
    )


def test_unit_headers_are_converted_to_the_si_units(tmp_path, scenario):
    """A run written in ms, mm, um, mA and rpm with its units in the header reads as the same
    run written in SI (issue 31, item 12)."""
    frame = with_speed(good_frame(scenario))
    si = read_measured_csv(write(tmp_path, frame))
    path = tmp_path / "units.csv"
    in_other_units(frame).to_csv(path, index=False)
    converted = read_measured_csv(path)
    for signal in ("t", "x_ref", "x", "current", "motor_speed"):
        np.testing.assert_allclose(converted.record[signal], si.record[signal], rtol=1e-12)
        assert converted.record.units[signal] == si.record.units[signal]
    check_against_reference(converted, scenario.reference)


@pytest.mark.parametrize(
    ("header", "message"),
    [
        ("x [furlong]", r"column 'x \[furlong\]': unknown unit 'furlong'"),
        ("x [rpm]", r"column 'x \[rpm\]': unit 'rpm' is a angular speed, but x is a length"),
        ("current [N.m]", r"unit 'N.m' is a torque, but current is a current or a voltage"),
    ],
)
def test_an_unknown_or_foreign_unit_is_an_error_naming_the_column(
    tmp_path, scenario, header, message
):
    frame = good_frame(scenario)
    frame = frame.rename(columns={header.split(" ")[0]: header})
    with pytest.raises(MeasuredDataError, match=message):
        read_measured_csv(write(tmp_path, frame))


def test_a_column_map_names_the_files_columns(tmp_path, scenario):
    frame = with_speed(good_frame(scenario))
    renamed = in_other_units(frame).rename(
        columns={"x [um]": "ActPos [um]", "t [ms]": "Time [ms]", "x_ref (mm)": "SetPos (mm)"}
    )
    path = tmp_path / "renamed.csv"
    renamed.to_csv(path, index=False)
    with pytest.raises(MeasuredDataError, match=r"missing column"):
        read_measured(path)
    columns = parse_columns("x=ActPos, t=Time,x_ref=SetPos")
    run = read_measured(path, columns)
    np.testing.assert_allclose(run.x, frame["x"], rtol=1e-12)
    np.testing.assert_allclose(run.t, frame["t"], rtol=1e-12)
    with pytest.raises(MeasuredDataError, match=r"names 'Nope' for 'x'"):
        read_measured(path, {"x": "Nope"})
    with pytest.raises(ValueError, match=r"--columns 'speed=v': 'speed' is not a signal"):
        parse_columns("speed=v")


def twincat_export(frame: pd.DataFrame, separator: str) -> str:
    """``frame`` (SI) as a TwinCAT Scope export: a time column per channel in ms, decimal comma,
    positions in mm, the current in mA, the speed in rpm."""
    channels = [
        ("SetPos", "x_ref", "mm (Millimeter)", 1e3),
        ("ActPos", "x", "mm (Millimeter)", 1e3),
        ("ActCurrent", "current", "mA (Milliampere)", 1e3),
        ("ActVelo", "motor_speed", "rpm", 60.0 / (2.0 * np.pi)),
    ]
    lines = [f"Name{separator}trace", f"File{separator}trace.csv", "", ""]
    for key, cell in (("Name", 0), ("SampleTime[ms]", None), ("Unit", 2)):
        lines.append(
            separator.join(
                f"{key}{separator}{'0,25' if cell is None else c[cell]}" for c in channels
            )
        )
    lines.append("")
    t_ms = frame["t"].to_numpy() * 1e3
    columns = [frame[signal].to_numpy() * factor for _, signal, _, factor in channels]
    for k, t in enumerate(t_ms):
        lines.append(
            separator.join(
                f"{float(t)!r}{separator}{float(values[k])!r}".replace(".", ",")
                for values in columns
            )
        )
    return "\n".join([*lines, "EOF", ""])


@pytest.mark.parametrize("separator", ["\t", ";"])
def test_a_twincat_scope_export_reads_as_the_si_run(tmp_path, scenario, separator):
    frame = with_speed(good_frame(scenario))
    si = read_measured_csv(write(tmp_path, frame))
    path = tmp_path / "scope.csv"
    path.write_text(twincat_export(frame, separator), encoding="utf-8")
    run = read_measured(
        path,
        {"x_ref": "SetPos", "x": "ActPos", "current": "ActCurrent"} | {"motor_speed": "ActVelo"},
    )
    for signal in ("t", "x_ref", "x", "current", "motor_speed"):
        np.testing.assert_allclose(run.record[signal], si.record[signal], rtol=1e-12, atol=1e-15)
    check_against_reference(run, scenario.reference)


def test_the_documented_twincat_example_reads():
    run = read_measured(
        TWINCAT_EXAMPLE,
        parse_columns("x_ref=SetPos,x=ActPos,current=ActCurrent,motor_speed=ActVelo"),
    )
    assert run.period == pytest.approx(1e-3)
    assert run.t[-1] == pytest.approx(0.399)
    assert np.max(run.x_ref) == pytest.approx(0.010, rel=1e-6)  # a 10 mm move, in m
    # its peak speed 2 x 10 mm / 0.3 s at 2 mm per revolution: 33.3 rev/s = 209 rad/s
    assert np.max(run.motor_speed) == pytest.approx(2 * 10 / 0.3 / 2 * 2 * np.pi, rel=1e-3)
    assert np.max(run.current) < 1.0  # written in mA, read in A
    with pytest.raises(MeasuredDataError, match=r"no channel named \['Pos'\]"):
        read_measured(TWINCAT_EXAMPLE, {"x": "Pos"})


def test_a_carriage_travels_and_a_rotor_turns():
    """A closed-loop run's carriage position runs along an axis (um in tables; figures in um,
    in mm beyond 10 mm); an open-loop rotor's angle (2 mm of load travel per rad here) has no
    travel and shows in rad: 1 m of load position is 500 rad."""
    carriage = position_label("current", 2e-3)
    assert carriage.travel and carriage.axis_words == "carriage position"
    assert carriage.figure_scale(5e-3) == ("um", 1e6)
    assert carriage.figure_scale(0.2) == ("mm", 1e3)
    rotor = position_label("motor_speed", 2e-3)
    assert not rotor.travel and rotor.axis_words == "rotor angle turned"
    assert rotor.figure_scale(5e-3) == rotor.figure_scale(0.2) == ("rad", 500.0)
    assert rotor.per_um == pytest.approx(5e-4)  # rad per um of load position
