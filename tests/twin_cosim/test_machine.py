"""The machine as judge: metrics there beside the twin's prediction."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.controller_set import FINE_TUNE
from twin_cosim.cosim import run_scenario
from twin_cosim.gap.synth import synthesize
from twin_cosim.machine import machine_metrics, model_error_margins, prediction
from twin_cosim.metrics import compute_metrics
from twin_cosim.model_error import ModelError
from twin_cosim.plant import Plant
from twin_cosim.scenario import load_scenario
from twin_cosim.scenario.plant_parameters import PlantParameters, write_plant_parameters

SHORT = scenario_text(speed=0.01, acceleration=0.1, move=0.4)


@pytest.fixture()
def scenario(tmp_path):
    path = tmp_path / "short.yaml"
    path.write_text(SHORT)
    return load_scenario(path)


def twin_metrics(scenario):
    with Plant(scenario.plant_fmu()) as plant:
        return compute_metrics(run_scenario(plant, scenario, FINE_TUNE))


def test_twin_on_itself_predicts_exactly(scenario, tmp_path):
    same = write_plant_parameters(tmp_path / "same.yaml", PlantParameters("drive2mass", {}))
    judged, kind = machine_metrics(scenario, FINE_TUNE, same)
    assert kind == "virtual machine"
    figures = prediction(twin_metrics(scenario), judged)
    assert all(f["relative_error_pct"] == 0.0 for f in figures.values())


def test_more_backlash_on_the_machine_shows_as_a_transfer_gap(scenario, tmp_path):
    machine = write_plant_parameters(
        tmp_path / "machine.yaml", PlantParameters("drive2mass", {"backlash": 40e-6})
    )
    judged, _ = machine_metrics(scenario, FINE_TUNE, machine)
    twin = twin_metrics(scenario)
    figures = prediction(twin, judged)
    assert judged.E_pk_um > twin.E_pk_um  # a larger dead zone at every reversal
    expected = 100 * (twin.E_pk_um - judged.E_pk_um) / judged.E_pk_um
    assert figures["E_pk_um"]["relative_error_pct"] == pytest.approx(expected)
    assert figures["E_pk_um"]["relative_error_pct"] < 0


def test_machine_given_as_a_scenario_keeps_the_trajectory(scenario, tmp_path):
    machine = tmp_path / "machine_scenario.yaml"
    machine.write_text(
        "plant:\n  parameters: {backlash: 40e-6}\nreference:\n  segments:\n    - dwell: 5.0\n"
    )
    by_scenario, _ = machine_metrics(scenario, FINE_TUNE, machine)
    file = write_plant_parameters(
        tmp_path / "machine.yaml", PlantParameters("drive2mass", {"backlash": 40e-6})
    )
    by_file, _ = machine_metrics(scenario, FINE_TUNE, file)
    assert by_scenario == by_file


def test_measured_run_is_judged_from_its_own_record(scenario, tmp_path):
    """A noise-free synthetic run made with the same gains gives the twin's own metrics."""
    run = synthesize(scenario, [], noise_position=0.0, noise_current=0.0).run
    path = Path(tmp_path / "run.csv")
    run.frame().to_csv(path, index=False)
    judged, kind = machine_metrics(scenario, FINE_TUNE, path)
    assert kind == "measured run"
    figures = prediction(twin_metrics(scenario), judged)
    for name in ("E_pk_um", "ITAE", "IAU"):
        assert abs(figures[name]["relative_error_pct"]) < 1e-6


def test_a_measured_run_in_other_units_and_names_is_judged_alike(scenario, tmp_path):
    """The same run written in um, mm and mA under a drive's column names, read through a
    column map: the same metrics as the SI file (issue 31, item 12)."""
    run = synthesize(scenario, [], seed=2).run
    si = tmp_path / "run.csv"
    run.frame().to_csv(si, index=False)
    frame = run.frame()
    other = tmp_path / "trace.csv"
    frame.assign(x=frame["x"] * 1e6, x_ref=frame["x_ref"] * 1e3, current=frame["current"] * 1e3)[
        ["t", "x_ref", "x", "current"]
    ].rename(
        columns={"x": "ActPos [um]", "x_ref": "SetPos [mm]", "current": "Iq [mA]", "t": "t [s]"}
    ).to_csv(other, index=False)
    by_si, _ = machine_metrics(scenario, FINE_TUNE, si)
    columns = {"x": "ActPos", "x_ref": "SetPos", "current": "Iq"}
    by_other, _ = machine_metrics(scenario, FINE_TUNE, other, columns)
    for name in ("E_pk_um", "ITAE", "IAU"):
        assert getattr(by_other, name) == pytest.approx(getattr(by_si, name), rel=1e-9)


def test_the_twin_s_held_out_error_widens_the_interval_to_hold_the_machine(scenario, tmp_path):
    """A machine with more backlash than the twin knows: outside the interval over the plant's
    intervals alone, inside once the interval carries the discrepancy a held-out run of that
    machine shows (its largest position gap: the bound of E_pk on one run)."""
    machine = write_plant_parameters(
        tmp_path / "machine.yaml", PlantParameters("drive2mass", {"backlash": 40e-6})
    )
    judged, _ = machine_metrics(scenario, FINE_TUNE, machine)
    twin = twin_metrics(scenario)
    with Plant(scenario.plant_fmu()) as plant:
        twin_run = run_scenario(plant, scenario, FINE_TUNE)
        machine_run = run_scenario(plant, scenario, FINE_TUNE, plant_overrides={"backlash": 40e-6})
    error = ModelError.of_discrepancy(
        machine_run["x"] - twin_run["x"], machine_run["current"] - twin_run["current"]
    )
    alone = prediction(twin, judged, [twin])["E_pk_um"]
    assert not alone["inside"] and alone["margin"] == 0.0
    margins = error.margins(scenario.reference.duration + scenario.settings.position_period)
    widened = prediction(twin, judged, [twin], margins)
    for name, f in widened.items():
        assert f["inside"], name
        assert f["low"] == max(f["spread_low"] - margins[name], 0.0)
        assert f["high"] == f["spread_high"] + margins[name]


def test_the_margins_come_from_the_plant_file_over_the_metrics_window(scenario, tmp_path):
    error = ModelError(position_peak_m=3e-7, position_rms_m=1e-7, current_rms_A=0.01)
    with_error = write_plant_parameters(
        tmp_path / "plant.yaml", PlantParameters("drive2mass", {}, model_error=error)
    )
    margins = model_error_margins(scenario, with_error)
    window = scenario.reference.duration + scenario.settings.position_period  # N samples
    assert margins == error.margins(window)
    assert margins["E_pk_um"] == pytest.approx(0.3)
    without = write_plant_parameters(tmp_path / "bare.yaml", PlantParameters("drive2mass", {}))
    assert model_error_margins(scenario, without) == {}
    assert model_error_margins(scenario, None) == {}
    figures = prediction(twin_metrics(scenario), twin_metrics(scenario), None, margins)
    assert figures["E_pk_um"]["high"] - figures["E_pk_um"]["low"] == pytest.approx(0.6)
