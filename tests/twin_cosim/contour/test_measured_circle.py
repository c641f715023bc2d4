"""Measured circular tests: read and checked, replayed by the twin, diagnosed per axis."""

from __future__ import annotations

import json

import pytest

from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, circle_motion
from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.contour.measured_circle import (
    diagnose_circle,
    read_measured_circle,
    replay_circle,
    synthesize_motion,
)
from twin_cosim.gap.synth import parse_effect
from twin_cosim.measured import MeasuredDataError
from twin_cosim.scenario import load_machine

SPEC = CircleSpec(0.01, 1000 * MM_PER_MIN, "ccw")


@pytest.fixture(scope="module")
def machine():
    return load_machine("xy_table")


def _write(machine, tmp_path, effects=None, **noise):
    table = synthesize_motion(machine, circle_motion(machine, SPEC)[0], effects or {}, **noise)
    path = tmp_path / "measured.csv"
    table.frame().to_csv(path, index=False)
    return path


def test_the_twin_replays_its_own_test_and_finds_no_gap(machine, tmp_path):
    path = _write(machine, tmp_path, noise_position=0.0, noise_current=0.0)
    measured = read_measured_circle(path)
    assert measured.direction == "ccw"
    assert measured.radius == pytest.approx(0.01, rel=1e-9)
    with MachinePlants(machine) as plants:
        replay = replay_circle(machine, measured, plants)
    assert max(replay.axis_gaps().values()) < 1e-3  # um
    assert replay.on_machine.G_um == pytest.approx(replay.on_twin.G_um, abs=0.05)
    for gap in replay.transition_gaps():
        assert gap["gap_um"] < 0.05


def test_a_test_is_checked_naming_the_file_and_column(machine, tmp_path):
    path = _write(machine, tmp_path)
    text = path.read_text().replace("y_ref", "yref", 1)
    path.write_text(text)
    with pytest.raises(MeasuredDataError, match="measured.csv: missing column.*y_ref"):
        read_measured_circle(path)
    line = tmp_path / "line.csv"
    line.write_text(
        "t,x_ref,y_ref,x,y\n" + "".join(f"{k * 1e-3},{k * 1e-5},0,0,0\n" for k in range(200))
    )
    with pytest.raises(MeasuredDataError, match="round a circle"):
        read_measured_circle(line)


@pytest.mark.slow
def test_the_diagnosis_names_the_axis_the_effect_and_the_transition(machine, tmp_path):
    effect = parse_effect("stribeck:stribeck_friction=0.3,stribeck_speed=0.47")
    path = _write(machine, tmp_path, {"Y": [effect]}, perturb=0.02, seed=1)
    found = diagnose_circle(machine, read_measured_circle(path))
    verdict = found["verdict"]
    assert verdict["axis"] == "Y" and verdict["effect"] == "stribeck"
    assert verdict["transition_deg"] in (90.0, 270.0)  # where Y reverses
    assert found["axes"]["X"]["accepted"] == []
    json.dumps({k: v for k, v in found.items() if k != "paths"})  # JSON-ready


def test_twin_circle_measured_prints_the_verdict(twin_cli, machine, tmp_path):
    path = _write(machine, tmp_path, noise_position=0.0, noise_current=0.0)
    path.write_text(
        "\n".join(",".join(row.split(",")[:5]) for row in path.read_text().splitlines()) + "\n"
    )  # without currents: the replay only
    done = twin_cli("circle", "xy_table", "--measured", str(path), "--out", str(tmp_path), "--json")
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout)
    assert found["axes"] == {} and found["verdict"]["axis"] is None
    assert len(found["transitions"]) == 4
    assert (tmp_path / "circle.png").is_file()
