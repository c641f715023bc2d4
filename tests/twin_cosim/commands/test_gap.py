"""``twin synth MACHINE``: a virtual machine's circular test or program run from the command line,
effects per axis, the geometric errors at the tool point, the known answer, refusals."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

MACHINE = """
axes:
  X:
    plant: {model: drive2mass}
    controller: {parameters: ft}
    limits: {velocity: 0.25, acceleration: 2.0, jerk: 40.0, travel: [-0.4, 0.4]}
  Y:
    plant: {model: drive2mass}
    controller: {parameters: ft}
    limits: {velocity: 0.25, acceleration: 2.0, jerk: 40.0, travel: [-0.4, 0.4]}
GEOMETRY
"""
SQUARENESS = 2000.0  # um/m


def _synth(twin_cli, *args: str):
    done = twin_cli("synth", *args, "--noise-position", "0", "--seed", "3")
    assert done.returncode == 0, done.stderr
    return done


def test_a_circle_of_a_virtual_machine_with_an_effect_in_one_axis_and_its_geometry(
    twin_cli, tmp_path
):
    nominal, bent = tmp_path / "nominal.yaml", tmp_path / "bent.yaml"
    nominal.write_text(MACHINE.replace("GEOMETRY", ""))
    bent.write_text(MACHINE.replace("GEOMETRY", f"geometry: {{squareness: {SQUARENESS}}}"))
    circle = ("--radius", "5", "--feed", "2000", "--direction", "cw")
    plain = tmp_path / "plain.csv"
    _synth(twin_cli, str(nominal), *circle, "--out", str(plain))
    backlash = tmp_path / "backlash.csv"
    done = _synth(
        twin_cli,
        str(nominal),
        *circle,
        "--effect",
        "Y:plant:backlash=40e-6",
        "--out",
        str(backlash),
    )
    assert "wrote" in done.stdout and "backlash.csv.truth.json" in done.stdout
    square = tmp_path / "square.csv"
    _synth(twin_cli, str(bent), *circle, "--out", str(square))

    runs = {path.stem: pd.read_csv(path) for path in (plain, backlash, square)}
    columns = ["t", "x_ref", "y_ref", "x", "y", "current_x", "current_y"]
    assert list(runs["plain"].columns) == columns
    t = runs["plain"]["t"].to_numpy()
    assert np.allclose(np.diff(t), 1e-3)  # every 4th sample of the 250 us position loop
    radius = np.hypot(runs["plain"]["x_ref"], runs["plain"]["y_ref"] - 0.0)
    assert radius.max() == pytest.approx(5e-3, rel=1e-3)

    # the axes do not interact: X runs as without the effect, Y lags by the play at reversals
    assert np.array_equal(runs["backlash"]["x"], runs["plain"]["x"])
    assert np.abs(runs["backlash"]["y"] - runs["plain"]["y"]).max() > 5e-6
    truth = json.loads((tmp_path / "backlash.csv.truth.json").read_text())
    assert truth["effects"] == {"Y": [{"name": "plant", "params": {"backlash": 40e-6}}]}
    assert truth["circle"] == {"radius_mm": 5.0, "feed_mm_min": 2000.0, "direction": "cw"}

    # squareness: +Y runs along (-alpha, 1); the axes' own positions are the nominal run's
    alpha = SQUARENESS * 1e-6
    plain_y = runs["plain"]["y"].to_numpy()
    assert np.allclose(runs["square"]["x"], runs["plain"]["x"] - alpha * plain_y, atol=1e-12)
    assert np.array_equal(runs["square"]["y"], plain_y)
    truth = json.loads((tmp_path / "square.csv.truth.json").read_text())
    assert truth["geometry"]["squareness"] == pytest.approx(SQUARENESS)


def test_a_program_run_of_a_virtual_machine_follows_the_program(twin_cli, tmp_path):
    program = tmp_path / "part.nc"
    program.write_text("%\nO0100\nG21 G90 G54 M03 S8000\nG01 X4 Y3 F1500\nG01 X0\nM05\nM30\n%\n")
    out = tmp_path / "run.csv"
    _synth(twin_cli, "xy_table", "--program", str(program), "--out", str(out))
    run = pd.read_csv(out)
    assert run["x_ref"].iloc[-1] == pytest.approx(0.0, abs=1e-9)
    assert run["y_ref"].iloc[-1] == pytest.approx(3e-3, rel=1e-9)
    # the corner at rest (G61); the position loop's reference a spline of the 4 ms samples
    assert run["x_ref"].max() == pytest.approx(4e-3, abs=0.05e-6)
    # 5 mm and 4 mm at 1500 mm/min, plus the ramps: at least 0.36 s
    assert run["t"].iloc[-1] > 9e-3 / 25e-3
    assert abs(run["y"].iloc[-1] - 3e-3) < 2e-6  # the axes settle where the program ends
    truth = json.loads(out.with_name("run.csv.truth.json").read_text())
    assert truth["program"] == str(program) and truth["effects"] == {}


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (("xy_table", "--effect", "stribeck:stribeck_friction=0.3"), "names its axis first"),
        (("xy_table", "--effect", "Z:stribeck:stribeck_friction=0.3"), "names its axis first"),
        (("xy_table", "--effect", "Y:wobble:a=1"), "'wobble' is not an effect"),
        (("xy_table", "--radius", "5"), "--radius MM and --feed MM_PER_MIN"),
        (("xy_table", "--radius", "5", "--feed", "900", "--follow", "x.csv"), "--follow"),
        (("reference1", "--radius", "5", "--feed", "900"), "for a machine scenario (axes:)"),
    ],
)
def test_a_machine_synth_refuses_what_it_cannot_run(twin_cli, tmp_path, args, said):
    out = tmp_path / "run.csv"
    done = twin_cli("synth", *args, "--out", str(out))
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert said in done.stderr, done.stderr
    assert not out.exists()
