"""Frequency responses measured on the twin against eqs. (3)-(4) and the linearised loops."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from twin_cosim.controller import ControllerSettings
from twin_cosim.controller_set import TABLE3
from twin_cosim.current_filters import Notch
from twin_cosim.frequency.bode import bode
from twin_cosim.frequency.linear import TwoMass
from twin_cosim.frequency.measurement import (
    MeasurementSettings,
    choose_bins,
    coherence,
    indirect_ratio,
    measure,
    multisine,
)
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import load_scenario

J_M, J_L, F_1, D_1 = 2.9e-4, 4.2e-4, 70.0, 0.15  # Table 1
W_01 = 2 * math.pi * F_1
W_02 = W_01 * math.sqrt(1 + J_L / J_M)
D_2 = D_1 * math.sqrt(1 + J_L / J_M)
LINEAR = plant_model("drive2mass").nonlinear_off


def eq3(f):
    s = 2j * np.pi * f
    return (s**2 + 2 * D_1 * W_01 * s + W_01**2) / (J_M * s * (s**2 + 2 * D_2 * W_02 * s + W_02**2))


@pytest.fixture(scope="module")
def reference1():
    return load_scenario("reference1")


def test_multisine_lines_avoid_each_others_images_and_have_the_rms():
    bins = choose_bins(16384, 2, 4096)
    residues = [b % 4096 for b in bins] + [-b % 4096 for b in bins if b % 2048]
    assert len(set(residues)) == len(residues)
    assert bins[-1] == 8192 and len(bins) > 200
    excitation = multisine(16384, 62.5e-6, 1.0, 0.7, 4096)
    signal = excitation.realisation(np.random.default_rng(1))
    assert np.sqrt(np.mean(signal**2)) == pytest.approx(0.7, rel=1e-9)


def test_h1_of_a_known_system_is_exact_and_coherent():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(6, 40)) + 1j * rng.normal(size=(6, 40))
    h = np.exp(1j * np.linspace(0, 3, 40)) * 2.0
    value, gamma = indirect_ratio(d, 3.0 * h * d, 3.0 * d)
    np.testing.assert_allclose(value, h)
    np.testing.assert_allclose(gamma, 1.0)
    assert np.all(coherence(d, rng.normal(size=(6, 40)) + 0j) < 0.9)


def test_plant_frf_with_nonlinearities_off_is_eq3(plant, reference1):
    """Goal: within 0.5 dB and 3 degrees over 10-500 Hz."""
    how = MeasurementSettings("plant")
    parameters = {**reference1.plant_parameters, **LINEAR}
    r = measure(plant, reference1.tuned, reference1.settings, parameters, how)
    band = (r.frequency_hz >= 10) & (r.frequency_hz <= 500)
    error = r.response[band] / eq3(r.frequency_hz[band]) / 1.0
    assert np.max(np.abs(20 * np.log10(np.abs(error)))) < 0.5
    assert np.max(np.abs(np.degrees(np.angle(error)))) < 3.0
    assert np.min(r.coherence) > 0.999


@pytest.mark.parametrize("loop", ["speed", "position"])
@pytest.mark.parametrize("name", ["ft", "ga"])
def test_measured_loop_margins_are_the_linearised_loops(reference1, loop, name):
    """Goal: within 1 dB and 2 degrees; the notch keeps the linearised loop honest too."""
    settings = ControllerSettings(filters=(Notch(110.0, 60.0, -12.0),))
    scenario = reference1.__class__(
        **{**reference1.__dict__, "tuned": TABLE3[name], "settings": settings}
    )
    result = bode(scenario, MeasurementSettings(loop), nonlinear=False)
    measured, linear = result.margins, result.linearised_margins
    assert measured.gain_margin_db == pytest.approx(linear.gain_margin_db, abs=1.0)
    assert measured.phase_margin_deg == pytest.approx(linear.phase_margin_deg, abs=2.0)
    assert measured.crossover_hz == pytest.approx(linear.crossover_hz, rel=0.02)
    assert measured.bandwidth_hz == pytest.approx(linear.bandwidth_hz, rel=0.02)
    deviation = result.deviation()
    assert deviation["max_db"] < 1e-3 and deviation["max_deg"] < 1e-2


def test_closed_loops_are_the_linearised_closed_loops(reference1):
    """Closed loops report their bandwidth (issue 35: as open loops do), measured and
    linearised."""
    for loop in ("speed", "position"):
        result = bode(reference1, MeasurementSettings(loop, "closed"), nonlinear=False)
        assert result.deviation()["max_db"] < 1e-3
        measured, linear = result.margins, result.linearised_margins
        assert measured.bandwidth_hz == pytest.approx(linear.bandwidth_hz, rel=0.02)
        assert measured.resonance_peak_db == pytest.approx(linear.resonance_peak_db, abs=0.1)


def test_backlash_and_friction_lower_the_coherence_at_low_frequency(reference1):
    result = bode(reference1, MeasurementSettings("plant", speed=0.0), nonlinear=True)
    drops = result.summary()["coherence_drops"]
    assert drops and drops[0]["from_hz"] < 10.0 and drops[0]["lowest"] < 0.5
    f, gamma = result.measured.frequency_hz, result.measured.coherence
    assert np.all(gamma[f > 300] > 0.95)  # above the resonances the motor moves alone


def test_speed_noise_lowers_the_coherence_but_not_the_estimate(reference1):
    how = MeasurementSettings("plant", speed_noise=0.05, seed=3)
    result = bode(reference1, how, nonlinear=False)
    f, r = result.measured.frequency_hz, result.measured.response
    band = (f >= 10) & (f <= 500)
    assert np.median(np.abs(20 * np.log10(np.abs(r[band] / eq3(f[band]))))) < 0.3
    assert np.min(result.measured.coherence) < 0.99


def test_bode_json_interface(twin_cli, tmp_path):
    result = twin_cli(
        "bode", "reference1", "--loop", "speed", "--open", "--nonlinear", "off",
        "--out", str(tmp_path), "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    for key in ("frequency_hz", "magnitude_db", "phase_deg", "coherence"):
        assert len(summary[key]) == len(summary["frequency_hz"]) > 100
    for key in ("gain_margin_db", "phase_margin_deg", "crossover_hz", "bandwidth_hz"):
        assert summary["margins"][key] is not None
    assert summary["margins"]["phase_margin_deg"] == pytest.approx(45.4, abs=0.2)
    for name in ("frf.csv", "bode.png", "nyquist.png", "bode.json"):
        assert (tmp_path / name).is_file()


def test_bode_refuses_a_closed_plant_and_bad_options(twin_cli, tmp_path):
    result = twin_cli("bode", "reference1", "--loop", "plant", "--closed", "--out", str(tmp_path))
    assert result.returncode == 2
    assert "the plant is measured open" in result.stderr and "Traceback" not in result.stderr
    result = twin_cli("bode", "reference1", "--loop", "disturbance", "--open")
    assert result.returncode == 2 and "--loop disturbance --open" in result.stderr
    result = twin_cli("bode", "reference1", "--loop", "speed", "--amplitude", "-1")
    assert result.returncode == 2 and "--amplitude" in result.stderr


def test_two_mass_of_a_changed_plant_follows_the_parameters():
    plant = TwoMass.of_plant("drive2mass", {"motor_inertia": 3.5e-4, "resonance_frequency": 60})
    assert plant.resonance_hz == pytest.approx(60 * math.sqrt(1 + 4.2e-4 / 3.5e-4))


@pytest.mark.parametrize("name", ["ft", "ga"])
def test_dynamic_stiffness_is_the_linearised_cascades(reference1, name):
    """Goal: at low frequency within 5 %, its minimum within 1 dB and 5 % in frequency, measured
    with the nonlinearities on at the default operating point (friction sliding, backlash
    closed)."""
    scenario = reference1.__class__(**{**reference1.__dict__, "tuned": TABLE3[name]})
    result = bode(scenario, MeasurementSettings("disturbance"), nonlinear=True)
    measured, linear = result.stiffness, result.linearised_stiffness
    assert measured.withheld == {}
    assert measured.low_frequency_n_per_um == pytest.approx(linear.low_frequency_n_per_um, rel=0.05)
    assert 20 * math.log10(measured.minimum_n_per_um / linear.minimum_n_per_um) == pytest.approx(
        0.0, abs=1.0
    )
    assert measured.minimum_hz == pytest.approx(linear.minimum_hz, rel=0.05)
    summary = result.summary()
    assert len(summary["stiffness_n_per_um"]) == len(summary["frequency_hz"])
    assert summary["unit"] == "N/um" and summary["margins"] is None


@pytest.mark.parametrize("loop", ["speed", "position"])
def test_closed_loop_bandwidth_with_the_nonlinearities_on(reference1, loop):
    """Goal: the closed loop's -3 dB bandwidth within 5 % of the linearised loop's, measured as
    a drive measures (nonlinearities on, the default operating point)."""
    result = bode(reference1, MeasurementSettings(loop, "closed"), nonlinear=True)
    measured, linear = result.margins, result.linearised_margins
    assert measured.bandwidth_hz == pytest.approx(linear.bandwidth_hz, rel=0.05)
    assert result.summary()["margins"]["bandwidth_hz"] == measured.bandwidth_hz
    assert result.summary()["linearised"]["margins"]["bandwidth_hz"] == linear.bandwidth_hz


def test_sensitivity_measured_is_one_over_one_plus_the_loop(reference1):
    for loop in ("speed", "position"):
        result = bode(reference1, MeasurementSettings(loop, "sensitivity"), nonlinear=False)
        assert result.deviation()["max_db"] < 1e-3
        assert result.margins.peak_sensitivity_db == pytest.approx(
            result.linearised_margins.peak_sensitivity_db, abs=0.1
        )


def test_margins_read_where_the_coherence_is_low_are_withheld(twin_cli, tmp_path):
    """Issue 31, item 2: at standstill friction sticks and the backlash opens; the margins read
    there are withheld in the text, the JSON and the plot's title. The default operating point
    measures where the loop is coherent."""
    result = twin_cli(
        "bode", "reference1", "--loop", "position", "--speed", "0", "--amplitude", "5.5e-5",
        "--out", str(tmp_path), "--no-plots",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "gain margin withheld" in result.stdout and "phase margin withheld" in result.stdout
    margins = json.loads((tmp_path / "bode.json").read_text())["margins"]
    assert margins["gain_margin_db"] is None and margins["phase_margin_deg"] is None
    assert margins["withheld"]["gain_margin_db"]["lowest_coherence"] < 0.9
    assert not (tmp_path / "bode.png").exists() and (tmp_path / "frf.csv").is_file()
    coherent = bode(load_scenario("reference1"), MeasurementSettings("position"), nonlinear=True)
    assert coherent.margins.withheld == {}
    linear = coherent.linearised_margins
    assert coherent.margins.gain_margin_db == pytest.approx(linear.gain_margin_db, abs=0.5)
    assert coherent.margins.phase_margin_deg == pytest.approx(linear.phase_margin_deg, abs=2.0)


def test_bode_disturbance_json_interface(twin_cli, tmp_path):
    result = twin_cli(
        "bode", "reference1", "--loop", "disturbance", "--averages", "2", "--out", str(tmp_path),
        "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["kind"] == "closed" and summary["unit"] == "N/um"
    for key in ("low_frequency_n_per_um", "minimum_n_per_um", "minimum_hz"):
        assert summary["stiffness"][key] > 0
        assert summary["linearised"]["stiffness"][key] > 0
    assert (tmp_path / "stiffness.png").is_file() and (tmp_path / "frf.csv").is_file()
