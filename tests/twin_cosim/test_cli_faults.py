"""User mistakes on the command line: exit 2 with a message naming the file or option."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.cli import main

SHORT = scenario_text(move=0.2, back=False, optimize="abort_error_um: 100.0")
ABSURD = "Kp_pos: 3000.0\nKp_vel: 0.05\nKi_vel: 0.03\nPP2: 5.0\nPP3: 0.1\nf_H: 0.5\n"


@pytest.fixture()
def scenario(tmp_path) -> Path:
    path = tmp_path / "short.yaml"
    path.write_text(SHORT)
    return path


def test_simulate_out_that_is_a_file(scenario, tmp_path, capsys):
    taken = tmp_path / "taken"
    taken.write_text("keep me")
    assert main(["simulate", str(scenario), "--out", str(taken)]) == 2
    err = capsys.readouterr().err
    assert f"--out {taken}: exists and is not a folder" in err
    assert taken.read_text() == "keep me"


def test_optimize_out_that_is_a_file(scenario, tmp_path, capsys):
    taken = tmp_path / "taken"
    taken.write_text("keep me")
    status = main(["optimize", str(scenario), "--method", "ce", "--out", str(taken)])
    assert status == 2
    assert f"--out {taken}: exists and is not a folder" in capsys.readouterr().err


def test_synth_never_overwrites_without_force(scenario, tmp_path, capsys):
    run = tmp_path / "run.csv"
    run.write_text("t,x_ref,x,current\n")  # stands for a real measured run
    assert main(["synth", str(scenario), "--out", str(run)]) == 2
    assert "exists (it may be a real measured run)" in capsys.readouterr().err
    assert run.read_text() == "t,x_ref,x,current\n"
    assert not (tmp_path / "run.csv.truth.json").exists()
    assert main(["synth", str(scenario), "--out", str(run), "--force"]) == 0
    assert len(run.read_text().splitlines()) > 100


def test_synth_out_that_is_a_folder(scenario, tmp_path, capsys):
    assert main(["synth", str(scenario), "--out", str(tmp_path)]) == 2
    assert f"--out {tmp_path}: is a folder" in capsys.readouterr().err


def test_simulate_warns_about_a_diverged_loop(scenario, tmp_path, capsys):
    params = tmp_path / "absurd.yaml"
    params.write_text(ABSURD)
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--params", str(params), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "warning: the loop diverged" in err
    assert "optimize.abort_error_um" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["warnings"][0].startswith("the loop diverged")
    assert summary["metrics"]["E_pk_um"] > 100.0


def test_a_well_tuned_run_has_no_warning(scenario, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--out", str(out)]) == 0
    assert json.loads((out / "summary.json").read_text())["warnings"] == []
    assert "warning" not in capsys.readouterr().err


def test_a_scenario_that_is_a_folder(tmp_path, capsys):
    assert main(["simulate", str(tmp_path)]) == 2
    assert f"{tmp_path}: is a folder, not a YAML file" in capsys.readouterr().err


def test_a_binary_scenario_is_named(tmp_path, capsys):
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(bytes(range(256)))
    assert main(["simulate", str(binary)]) == 2
    assert f"{binary}: not a text (YAML) file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["diagnose", "s.yaml", "--measured", "r.csv", "--max-effects", "-1"], "--max-effects"),
        (["diagnose", "s.yaml", "--measured", "r.csv", "--workers", "0"], "--workers"),
        (["diagnose", "s.yaml", "--measured", "r.csv", "--split", "2"], "--split"),
        (["compare", "c.yaml", "--workers", "-2"], "--workers"),
        (["synth", "s.yaml", "--out", "r.csv", "--seed", "-1"], "--seed"),
        (["optimize", "s.yaml", "--budget", "ten"], "--budget"),
    ],
)
def test_bad_numbers_name_their_option(argv, expected, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {expected}: expected" in err


def test_an_out_folder_that_cannot_be_made_is_named(scenario, tmp_path, capsys):
    taken = tmp_path / "taken"
    taken.write_text("keep me")
    assert main(["simulate", str(scenario), "--out", str(taken / "sub")]) == 2
    err = capsys.readouterr().err
    assert str(taken / "sub") in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("effect", "says"),
    [
        (
            "stribeck:stribeck_friction=0.2,stribeck_speed=-0.4",
            "--effect stribeck:stribeck_friction=0.2,stribeck_speed=-0.4: sets stribeck_speed: "
            "-0.4 rad/s outside the model's range (0, ",
        ),
        (
            "plant:coulomb_asymmetry=0.7",
            "--effect plant:coulomb_asymmetry=0.7: the plant would break |coulomb_asymmetry| <= "
            "coulomb_friction (coulomb_asymmetry = 0.7 N.m, coulomb_friction = 0.625 N.m)",
        ),
    ],
)
def test_synth_refuses_what_the_fmu_would_refuse_before_it_runs(
    scenario, tmp_path, capsys, effect, says
):
    """Issue 31, item 8: a value the FMU would refuse is named with its option and range, not
    answered with the FMU's path and an fmi2SetReal status."""
    run = tmp_path / "run.csv"
    assert main(["synth", str(scenario), "--effect", effect, "--out", str(run)]) == 2
    err = capsys.readouterr().err
    assert says in err
    assert "fmi2" not in err
    assert not run.exists()


def test_plant_parameters_the_fmu_would_refuse_are_named_before_it_runs(scenario, tmp_path, capsys):
    plant = tmp_path / "plant.yaml"
    plant.write_text("model: drive2mass\nparameters: {coulomb_asymmetry: -0.7}\n")
    out = tmp_path / "out"
    code = main(["simulate", str(scenario), "--plant-parameters", str(plant), "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert f"{plant}: parameters.coulomb_asymmetry: the plant would break" in err
    assert "fmi2" not in err
