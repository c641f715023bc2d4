"""The twin-to-machine loop on the command line: plant.yaml -> optimize, simulate --machine.

``twin diagnose`` writing plant.yaml and calibrated.yaml is tested in test_plant_parameters.py.
"""

from __future__ import annotations

import json

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
