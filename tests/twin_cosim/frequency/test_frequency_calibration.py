"""FRF files refused or masked with the file, column and frequency named; the two-mass fit."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from twin_cosim.frequency.calibration import fit_two_mass, read_frf
from twin_cosim.frequency.linear import TwoMass
from twin_cosim.measured import MeasuredDataError

F = np.geomspace(2.0, 1000.0, 200)
TABLE1 = TwoMass.from_paper(2.9e-4, 4.2e-4, 70.0, 0.15)


def write_csv(path, f, h, coherence=None, polar=True):
    columns = {"f": f}
    if polar:
        columns |= {"magnitude_db": 20 * np.log10(np.abs(h)), "phase_deg": np.degrees(np.angle(h))}
    else:
        columns |= {"real": h.real, "imag": h.imag}
    if coherence is not None:
        columns["coherence"] = coherence
    lines = [",".join(columns)]
    for row in zip(*columns.values(), strict=True):
        lines.append(",".join(f"{v:.12g}" for v in row))
    path.write_text("# a plant FRF\n" + "\n".join(lines) + "\n")
    return path


def noisy(plant, noise, seed):
    rng = np.random.default_rng(seed)
    h = plant.speed_per_torque(F)
    return h * (1 + noise * (rng.normal(size=len(F)) + 1j * rng.normal(size=len(F))) / np.sqrt(2))


@pytest.mark.parametrize("seed", range(8))
def test_fit_recovers_each_parameter_within_3_percent_of_a_changed_machine(seed):
    """Goal: J_M, J_L, f_1, D_1 each changed by up to 20 %, a noisy FRF (5 % per line)."""
    factors = np.random.default_rng(100 + seed).uniform(0.8, 1.2, 4)
    truth = TwoMass.from_paper(
        2.9e-4 * factors[0], 4.2e-4 * factors[1], 70 * factors[2], 0.15 * factors[3]
    )
    fit = fit_two_mass(F, noisy(truth, 0.05, seed), np.full(len(F), 0.9975))
    found = fit.plant
    assert found.motor_inertia == pytest.approx(truth.motor_inertia, rel=0.03)
    assert found.load_inertia == pytest.approx(truth.load_inertia, rel=0.03)
    assert found.antiresonance_hz == pytest.approx(truth.antiresonance_hz, rel=0.03)
    assert found.damping_ratio == pytest.approx(truth.damping_ratio, rel=0.03)


def test_fit_finds_viscous_friction_and_a_delay():
    truth = TABLE1.with_values(viscous_friction=0.02)
    h = truth.speed_per_torque(F) * np.exp(-2j * np.pi * F * 1e-4)
    fit = fit_two_mass(F, h)
    assert fit.plant.viscous_friction == pytest.approx(0.02, rel=1e-3)
    assert fit.delay_s == pytest.approx(1e-4, rel=1e-3)
    assert fit.rms_db < 1e-3
    assert fit.drive_terms()["delay_s"] == pytest.approx(1e-4, rel=1e-3)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_delay_and_a_lag_the_data_do_not_hold_are_not_identified(seed):
    """Issue 31, item 9: a fit to an FRF without delay nor lag gives no negative delay, and
    reports both as not identified rather than a fraction of a microsecond."""
    fit = fit_two_mass(F, noisy(TABLE1, 0.01, seed), np.full(len(F), 0.999))
    assert fit.delay_s >= 0.0 and fit.lag_s >= 0.0
    assert fit.drive_terms() == {"delay_s": None, "current_lag_s": None}
    assert set(fit.not_identified()) == {"delay_s", "current_lag_s"}
    assert "not identified" in fit.drive_text()


@pytest.mark.parametrize("seed", [0, 1])
def test_a_viscous_friction_the_fit_holds_at_its_bound_is_zero(seed):
    """A plant without viscous friction: the fit holds it at its lower bound, and reports the
    bound (0 N.m.s/rad), not a number of the solver's tolerance (about 1e-35)."""
    assert TABLE1.viscous_friction == 0.0
    fit = fit_two_mass(F, noisy(TABLE1, 0.01, seed), np.full(len(F), 0.999))
    assert fit.plant.viscous_friction == 0.0
    assert fit.plant.motor_inertia == pytest.approx(TABLE1.motor_inertia, rel=0.03)


def test_a_delay_and_a_lag_the_data_hold_are_identified():
    truth = TABLE1.with_values(dead_time=125e-6, current_lag=2e-4, torque_constant=1.0)
    h = truth.speed_per_torque(F) * truth.torque_per_current(F)
    fit = fit_two_mass(F, h)
    terms = fit.drive_terms()
    assert terms["delay_s"] == pytest.approx(125e-6, rel=0.02)
    assert terms["current_lag_s"] == pytest.approx(2e-4, rel=0.02)


def test_a_real_imaginary_file_reads_as_the_polar_one(tmp_path):
    h = TABLE1.speed_per_torque(F)
    polar = read_frf(write_csv(tmp_path / "a.csv", F, h))
    cartesian = read_frf(write_csv(tmp_path / "b.csv", F, h, polar=False))
    np.testing.assert_allclose(polar.response, cartesian.response, rtol=1e-9)
    assert polar.coherence is None and polar.used.all()


def test_low_coherence_bands_are_masked_and_named(tmp_path):
    coherence = np.where((F > 40) & (F < 60), 0.3, 0.99)
    data = read_frf(write_csv(tmp_path / "c.csv", F, TABLE1.speed_per_torque(F), coherence))
    assert data.used.sum() == np.sum(~((F > 40) & (F < 60)))
    (note,) = data.notes(0.8)
    assert "c.csv: column coherence below 0.8 from 40" in note and "masked" in note


def frf_lines(tmp_path, edit):
    path = write_csv(tmp_path / "bad.csv", F, TABLE1.speed_per_torque(F), np.full(len(F), 0.99))
    lines = path.read_text().splitlines()
    edit(lines)
    path.write_text("\n".join(lines) + "\n")
    return path


def set_cell(row, column, value):
    def edit(lines):
        cells = lines[row + 2].split(",")
        cells[column] = value
        lines[row + 2] = ",".join(cells)

    return edit


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (set_cell(50, 2, "nan"), r"column phase_deg: 'nan', not a finite number at f = \d"),
        (set_cell(50, 1, ""), r"column magnitude_db: a missing value \(a gap\) at f = \d"),
        (set_cell(60, 0, "1.0"), "column f: frequencies not increasing at f = "),
        (set_cell(70, 3, "1.5"), r"column coherence: 1.5 at f = .* is outside \[0, 1\]"),
        (lambda lines: lines.__delitem__(slice(80, 120)), "column f: a gap, no line between"),
        (lambda lines: lines.__setitem__(1, "f,gain,phase_deg,coherence"), "expected columns"),
        (lambda lines: lines.__delitem__(slice(8, None)), "a fit needs at least 8"),
    ],
)
def test_bad_files_are_refused_naming_file_column_and_frequency(tmp_path, edit, message):
    path = frf_lines(tmp_path, edit)
    with pytest.raises(MeasuredDataError, match=message) as info:
        read_frf(path)
    assert str(path) in str(info.value)


def test_too_few_coherent_lines_are_refused(tmp_path):
    path = write_csv(tmp_path / "d.csv", F, TABLE1.speed_per_torque(F), np.full(len(F), 0.5))
    with pytest.raises(MeasuredDataError, match="only 0 lines at or above the coherence floor"):
        read_frf(path)


def test_calibrate_writes_plant_yaml_with_provenance(tmp_path, twin_cli):
    truth = TwoMass.from_paper(3.4e-4, 3.6e-4, 80.0, 0.12)
    frf = write_csv(tmp_path / "m.csv", F, noisy(truth, 0.02, 1), np.full(len(F), 0.9996))
    beside = tmp_path / "diag.yaml"
    beside.write_text("model: drive2mass\nparameters: {motor_inertia: 3.0e-4}\n")
    out = tmp_path / "cal"
    result = twin_cli(
        "calibrate", "reference1", "--frf", str(frf), "--out", str(out), "--beside", str(beside),
        "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    plant = yaml.safe_load((out / "plant.yaml").read_text())
    assert plant["model"] == "drive2mass"
    assert plant["parameters"]["motor_inertia"] == pytest.approx(3.4e-4, rel=0.03)
    assert plant["parameters"]["resonance_frequency"] == pytest.approx(80.0, rel=0.03)
    assert "fitted to the plant FRF" in plant["provenance"]["load_inertia"]["source"]
    summary = json.loads(result.stdout)
    assert summary["table"][0]["beside"] == 3.0e-4 and summary["table"][1]["beside"] is None
    for name in ("calibration.md", "fit.png", "calibration.json"):
        assert (out / name).is_file()


def test_calibrate_refuses_a_bad_file_with_status_2(tmp_path, twin_cli):
    path = frf_lines(tmp_path, set_cell(30, 1, "abc"))
    result = twin_cli("calibrate", "reference1", "--frf", str(path), "--out", str(tmp_path / "o"))
    assert result.returncode == 2
    assert "column magnitude_db: 'abc', not a finite number at f = " in result.stderr
    assert "Traceback" not in result.stderr


def test_the_twins_noisy_frf_of_a_changed_machine_calibrates_it(tmp_path, twin_cli):
    """Goal, end to end: twin bode on a machine 15-20 % off Table 1, speed noise, then fit."""
    truth = {
        "motor_inertia": 2.9e-4 * 1.2,
        "load_inertia": 4.2e-4 * 0.85,
        "resonance_frequency": 70.0 * 1.15,
        "damping_ratio": 0.15 * 0.8,
    }
    machine = tmp_path / "machine.yaml"
    machine.write_text(yaml.safe_dump({"model": "drive2mass", "parameters": truth}))
    measured = twin_cli(
        "bode", "reference1", "--loop", "plant", "--nonlinear", "off", "--noise", "0.1",
        "--plant-parameters", str(machine), "--out", str(tmp_path / "bode"),
    )  # fmt: skip
    assert measured.returncode == 0, measured.stderr
    calibrated = twin_cli(
        "calibrate", "reference1", "--frf", str(tmp_path / "bode" / "frf.csv"),
        "--out", str(tmp_path / "cal"),
    )  # fmt: skip
    assert calibrated.returncode == 0, calibrated.stderr
    found = yaml.safe_load((tmp_path / "cal" / "plant.yaml").read_text())["parameters"]
    for name, value in truth.items():
        assert found[name] == pytest.approx(value, rel=0.03), name
