"""Hostile or absurd scenarios: refused by name, before anything is built or allocated."""

from __future__ import annotations

import time

import pytest

from twin_cosim.cli import main
from twin_cosim.scenario import ScenarioError, load_scenario

RAMP = """
reference:
  sample_period: {period}
  segments:
    - dwell: 0.1
    - ramp: {{velocity: 0.005, acceleration: 0.05, duration: {duration}}}
    - ramp: {{velocity: 0.0, acceleration: 0.05, duration: 0.1}}
"""


def write(tmp_path, text: str, name: str = "s.yaml"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("name", ["../../../../outside/x", "/abs", "a/b", "..", ".hidden", ""])
def test_a_name_that_is_not_a_plain_file_name_is_refused(tmp_path, name):
    path = write(tmp_path, f"name: {name!r}\n" + RAMP.format(period=0.004, duration=0.2))
    with pytest.raises(ScenarioError, match=r"s.yaml: name: expected a plain file name"):
        load_scenario(path)


def test_a_name_cannot_lead_simulate_out_of_the_working_folder(tmp_path, monkeypatch, capsys):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    path = write(tmp_path, "name: ../escaped\n" + RAMP.format(period=0.004, duration=0.2))
    assert main(["simulate", str(path)]) == 2
    assert "name: expected a plain file name" in capsys.readouterr().err
    assert not (tmp_path / "escaped").exists()


def test_plant_model_must_be_one_of_the_project(tmp_path):
    path = write(tmp_path, "plant: {model: ../../x}\n" + RAMP.format(period=0.004, duration=0.2))
    with pytest.raises(ScenarioError, match=r"plant.model: expected one of the project's models"):
        load_scenario(path)


@pytest.mark.parametrize(
    ("period", "duration", "message"),
    [
        (1e-9, 0.2, "reference: reference sample_period 1e-09 s must be a whole multiple"),
        (
            0.004,
            1e6,
            r"reference.segments: 1e\+06 s at the position-loop period .* run.max_samples",
        ),
        (100, 0.2, r"reference.sample_period: expected at most the reference's duration"),
    ],
    ids=["tiny-period", "huge-duration", "period-longer-than-run"],
)
def test_run_size_is_checked_before_allocating(tmp_path, period, duration, message):
    path = write(tmp_path, RAMP.format(period=period, duration=duration))
    start = time.monotonic()
    with pytest.raises(ScenarioError, match=message):
        load_scenario(path)
    assert time.monotonic() - start < 5  # refused without allocating gigabytes


def test_the_size_limit_is_a_scenario_setting(tmp_path):
    text = RAMP.format(period=0.004, duration=0.2) + "run: {max_samples: 1000}\n"
    with pytest.raises(ScenarioError, match="more than run.max_samples = 1000"):
        load_scenario(write(tmp_path, text))
    raised = RAMP.format(period=0.004, duration=0.2) + "run: {max_samples: 2000}\n"
    assert len(load_scenario(write(tmp_path, raised, "r.yaml")).reference.position) == 1601


def test_plant_parameters_that_break_a_constraint_of_the_card_are_refused(tmp_path):
    """Each within its range, together refused by the FMU at initialisation: named before it
    runs (issue 31, item 8)."""
    plant = (
        "plant: {model: hsm150, parameters: {coulomb_friction: 0.01, coulomb_asymmetry: 0.02}}\n"
    )
    path = write(tmp_path, plant + RAMP.format(period=0.004, duration=0.2))
    with pytest.raises(
        ScenarioError,
        match=r"s.yaml: plant.parameters.coulomb_asymmetry, plant.parameters.coulomb_friction: "
        r"the plant would break \|coulomb_asymmetry\| <= coulomb_friction",
    ):
        load_scenario(path)
