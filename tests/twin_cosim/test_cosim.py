"""The co-simulation master: both paths agree, any contract FMU runs, failures stop with the log."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twin_cosim.cosim import RECORD_COLUMNS, run_scenario
from twin_cosim.plant import Plant, PlantError
from twin_cosim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


@pytest.fixture(scope="module")
def reference1():
    return load_scenario(SCENARIOS / "reference1.yaml")


def test_fast_and_reference_paths_agree_on_reference1(plant, reference1):
    fast = run_scenario(plant, reference1, fast=True)
    slow = run_scenario(plant, reference1, fast=False)
    assert list(fast.columns) == list(RECORD_COLUMNS)
    assert len(fast) == len(reference1.reference.position)
    assert np.max(np.abs(fast["x"] - slow["x"])) < 1e-9
    assert np.max(np.abs(fast["current"] - slow["current"])) < 1e-9


def test_reset_between_runs_repeats_the_run(plant, reference1):
    first = run_scenario(plant, reference1)
    second = run_scenario(plant, reference1)
    assert first.equals(second)


def test_time_is_index_times_period(plant, reference1):
    record = run_scenario(plant, reference1)
    assert np.array_equal(record["t"].to_numpy(), np.arange(len(record)) * 250e-6)


def test_another_fmu_with_the_contract_runs(fmu_path, reference1, tmp_path):
    copy = tmp_path / "vendor_axis.fmu"
    shutil.copy(fmu_path, copy)
    with Plant(copy) as other, Plant(fmu_path) as ours:
        assert run_scenario(other, reference1).equals(run_scenario(ours, reference1))


def rewrite_description(fmu_path: Path, target: Path, old: str, new: str) -> Path:
    with zipfile.ZipFile(fmu_path) as source, zipfile.ZipFile(target, "w") as out:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(old.encode(), new.encode())
            out.writestr(item, data)
    return target


def test_fmu_without_the_contract_is_refused(fmu_path, tmp_path):
    broken = rewrite_description(
        fmu_path, tmp_path / "broken.fmu", 'name="load_position"', 'name="x_load"'
    )
    with pytest.raises(
        PlantError, match="does not offer the plant contract: missing output 'load_position'"
    ):
        Plant(broken)


def test_missing_and_corrupt_fmu_are_named(tmp_path):
    with pytest.raises(PlantError, match="FMU file not found"):
        Plant(tmp_path / "nothing.fmu")
    junk = tmp_path / "junk.fmu"
    junk.write_text("not a zip")
    with pytest.raises(PlantError, match="not an FMU"):
        Plant(junk)


@pytest.mark.parametrize("fast", [True, False])
def test_failing_fmu_stops_the_run_with_its_message(plant, reference1, fast):
    # A 20 kHz coupling cannot be integrated with 4 substeps of 62.5 us: doStep fails.
    with pytest.raises(PlantError, match="too long"):
        run_scenario(plant, reference1, fast=fast, plant_overrides={"resonance_frequency": 20000.0})
    run_scenario(plant, reference1)  # and the plant is usable again


def test_unknown_plant_parameter_is_named(plant, reference1):
    with pytest.raises(PlantError, match="no parameter named 'stiffnes'"):
        run_scenario(plant, reference1, plant_overrides={"stiffnes": 1.0})


@pytest.mark.parametrize("recorded", [False, True])
def test_a_command_disturbance_is_cancelled_by_the_integral_action(plant, tmp_path, recorded):
    """A constant offset added to the controller's output before the plant, at standstill
    without friction or backlash: the speed loop's integral drives its own output to minus the
    offset and the position error to zero; the recorded command includes the offset exactly
    when the scenario says the measured one does."""
    import dataclasses

    text = (SCENARIOS / "reference1.yaml").read_text().split("reference:")[0]
    path = tmp_path / "dwell.yaml"
    path.write_text(text + "reference:\n  sample_period: 0.004\n  segments:\n    - dwell: 1.5\n")
    scenario = load_scenario(path)
    offset = 0.2  # A
    n = len(scenario.reference.position)
    dwell = dataclasses.replace(
        scenario, command_disturbance=np.full(n, offset), disturbance_in_record=recorded
    )
    ideal = {"coulomb_friction": 0.0, "viscous_friction": 0.0, "backlash": 0.0}
    fast = run_scenario(plant, dwell, plant_overrides=ideal)
    slow = run_scenario(plant, dwell, fast=False, plant_overrides=ideal)
    assert np.max(np.abs(fast["current"] - slow["current"])) < 1e-9
    early = fast["current"][fast["t"] < 0.05].to_numpy() - (offset if recorded else 0.0)
    assert early.min() < -offset  # the loop first answers the push, then settles
    end = fast["t"] > 1.0
    expected = 0.0 if recorded else -offset
    assert fast["current"][end].to_numpy() == pytest.approx(expected, abs=1e-6)
    assert np.max(np.abs(fast["x"][end])) < 1e-12
