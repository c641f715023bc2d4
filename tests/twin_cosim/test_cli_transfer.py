"""The twin-to-machine loop on the command line: plant.yaml -> optimize, simulate --machine.

``twin diagnose`` writing plant.yaml and calibrated.yaml is tested in test_plant_parameters.py.
"""

from __future__ import annotations

import json

import pytest
import yaml
from scenario_texts import scenario_text

from twin_cosim import cli

MOVES = {"speed": 0.02, "acceleration": 0.2, "move": 1.0, "stop": 0.2, "dwell": 0.3}
SHORT = scenario_text(**MOVES)


def test_simulate_on_a_virtual_machine_reports_the_prediction_error(tmp_path, capsys):
    (tmp_path / "short.yaml").write_text(SHORT)
    machine = tmp_path / "machine.yaml"
    machine.write_text(yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": 30e-6}}))
    calibrated = tmp_path / "plant.yaml"
    calibrated.write_text(
        yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": 29e-6}})
    )
    common = ["simulate", str(tmp_path / "short.yaml"), "--machine", str(machine)]
    assert cli.main([*common, "--out", str(tmp_path / "n")]) == 0
    assert "twin predicted" in capsys.readouterr().out
    assert (
        cli.main([*common, "--plant-parameters", str(calibrated), "--out", str(tmp_path / "c")])
        == 0
    )
    far, near = (
        json.loads((tmp_path / name / "summary.json").read_text())["machine"]["E_pk_um"]
        for name in ("n", "c")
    )
    assert far["machine"] == near["machine"]  # the same machine judges both
    assert abs(near["relative_error_pct"]) < abs(far["relative_error_pct"])


def test_optimize_with_plant_parameters_and_two_scenarios(tmp_path, capsys):
    (tmp_path / "a.yaml").write_text(SHORT)
    (tmp_path / "b.yaml").write_text(scenario_text("b", **MOVES))
    calibrated = tmp_path / "plant.yaml"
    calibrated.write_text(
        yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": 20e-6}})
    )
    a, b, out = str(tmp_path / "a.yaml"), str(tmp_path / "b.yaml"), str(tmp_path / "c")
    robust = ["--plant-parameters", str(calibrated), "--samples", "2", "--tolerance", "0.03"]
    common = ["--method", "ce", "--budget", "10", "--workers", "1", "--quiet"]
    assert cli.main(["optimize", a, b, *robust, *common, "--json", "--out", out]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert len(summary["metrics"]["runs"]) == 4
    assert cli.main(["optimize", a, "--resume", out, "--samples", "3"]) == 2
    assert "samples" in capsys.readouterr().err


def test_bad_plant_parameters_file_is_a_clear_error(tmp_path, capsys):
    (tmp_path / "short.yaml").write_text(SHORT)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": -1.0}}))
    scenario = str(tmp_path / "short.yaml")
    code = cli.main(["simulate", scenario, "--plant-parameters", str(bad), "--out", str(tmp_path)])
    assert code == 2
    error = capsys.readouterr().err
    assert f"{bad}: parameters.backlash" in error
    assert "Traceback" not in error


def _plant_with_intervals(path, backlash, interval):
    path.write_text(
        yaml.safe_dump(
            {
                "model": "drive2mass",
                "parameters": {"backlash": backlash},
                "intervals": {"backlash": list(interval)},
            }
        )
    )
    return path


def test_optimize_tunes_over_the_plant_files_intervals_by_default(tmp_path, capsys):
    (tmp_path / "a.yaml").write_text(SHORT)
    plant = _plant_with_intervals(tmp_path / "plant.yaml", 20e-6, (18e-6, 24e-6))
    common = ["--method", "ce", "--budget", "6", "--workers", "1", "--quiet", "--json"]
    given = ["optimize", str(tmp_path / "a.yaml"), "--plant-parameters", str(plant), *common]
    assert cli.main([*given, "--out", str(tmp_path / "robust")]) == 0
    assert len(json.loads(capsys.readouterr().out)["metrics"]["runs"]) == 4
    robust = json.loads((tmp_path / "robust" / "campaign.json").read_text())["robust"]
    assert robust["uncertain_parameters"] == ["backlash"]
    assert robust["intervals"]["backlash"] == pytest.approx([0.9, 1.2])
    assert robust["samples"][0] == {}
    assert all(0.9 <= s["backlash"] <= 1.2 for s in robust["samples"][1:])
    assert cli.main([*given, "--samples", "1", "--out", str(tmp_path / "nominal")]) == 0
    assert "runs" not in json.loads(capsys.readouterr().out)["metrics"]  # the nominal plant only
    assert (
        json.loads((tmp_path / "nominal" / "campaign.json").read_text())["robust"]["samples"] == []
    )


def test_simulate_states_the_predictions_interval_and_whether_it_holds(tmp_path, capsys):
    """The machine's backlash inside the plant file's interval: its E_pk inside the predicted
    interval (E_pk grows with the backlash); an interval that misses it: outside."""
    (tmp_path / "short.yaml").write_text(SHORT)
    machine = tmp_path / "machine.yaml"
    machine.write_text(yaml.safe_dump({"model": "drive2mass", "parameters": {"backlash": 30e-6}}))
    found = {}
    for name, interval in (("wide", (25e-6, 35e-6)), ("narrow", (28e-6, 29.5e-6))):
        plant = _plant_with_intervals(tmp_path / f"{name}.yaml", 29e-6, interval)
        argv = ["simulate", str(tmp_path / "short.yaml"), "--machine", str(machine)]
        argv += ["--plant-parameters", str(plant), "--no-plots", "--out", str(tmp_path / name)]
        assert cli.main(argv) == 0
        found[name] = capsys.readouterr().out
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        e_pk = summary["machine"]["E_pk_um"]
        assert e_pk["low"] <= e_pk["twin"] <= e_pk["high"]
        assert e_pk["inside"] == (name == "wide")
        assert e_pk["inside"] == (e_pk["low"] <= e_pk["machine"] <= e_pk["high"])
    assert "(the plant's intervals " in found["wide"]
    assert "held-out error" not in found["wide"]  # a plant file without a model_error
    assert found["wide"].count("the machine inside") == 3
    assert "E_pk" in found["narrow"].split("the machine outside")[0].splitlines()[-1]
