"""Current-setpoint filters against their analytic responses, in the controller, on both paths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim import controller as c
from twin_cosim import current_filters as cf
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.cosim import AxisRun, run_axes
from twin_cosim.current_filters import LowPass, Notch
from twin_cosim.reference import Dwell, Ramp, interpolate, sample_segments
from twin_cosim.scenario import ScenarioError, load_scenario
from twin_cosim.scenario.controller_section import filters_section
from twin_cosim.schema import Checker


def run_axis(plant, grid, tuned, settings, plant_parameters=None, fast=True):
    """One axis on the master, its record per position-loop sample."""
    axis = AxisRun("X", plant, grid, tuned, settings, plant_parameters or {})
    return run_axes([axis], fast)["X"].position_loop


T = 62.5e-6  # s, speed-loop period
NOTCH = Notch(frequency_hz=110.0, bandwidth_hz=40.0, depth_db=-20.0)
LOWPASS = LowPass(frequency_hz=900.0, damping=0.5)


@pytest.mark.parametrize("section", [NOTCH, LOWPASS])
def test_tustin_prewarped_is_the_prototype_on_the_warped_axis(section):
    f = np.geomspace(1.0, 7900.0, 400)
    w0 = 2 * np.pi * section.frequency_hz
    k = w0 / np.tan(w0 * T / 2)
    warped = k * np.tan(np.pi * f * T) / (2 * np.pi)  # Hz: s = K (z - 1)/(z + 1) on |z| = 1
    np.testing.assert_allclose(
        cf.discrete_response(section, f, T), cf.continuous_response(section, warped), rtol=1e-9
    )
    at = np.array([section.frequency_hz])
    np.testing.assert_allclose(
        cf.discrete_response(section, at, T), cf.continuous_response(section, at), rtol=1e-9
    )


def test_notch_depth_and_bandwidth_as_drives_set_them():
    at = np.array([NOTCH.frequency_hz])
    assert 20 * np.log10(abs(cf.continuous_response(NOTCH, at)[0])) == pytest.approx(-20.0)
    full = Notch(110.0, 40.0, -300.0)  # full depth: B is the -3 dB width
    zeta = 40.0 / (2 * 110.0)
    edges = 110.0 * (np.sqrt(1 + zeta**2) + np.array([-zeta, zeta]))
    assert edges[1] - edges[0] == pytest.approx(40.0)
    np.testing.assert_allclose(np.abs(cf.continuous_response(full, edges)), 1 / math.sqrt(2))
    assert abs(cf.discrete_response(NOTCH, np.array([0.0]), T)[0]) == pytest.approx(1.0)


def test_lowpass_peak_and_butterworth_corner():
    at = np.array([LOWPASS.frequency_hz])
    assert abs(cf.continuous_response(LOWPASS, at)[0]) == pytest.approx(1 / (2 * 0.5))
    butterworth = LowPass(500.0)
    corner = abs(cf.discrete_response(butterworth, np.array([500.0]), T)[0])
    assert corner == pytest.approx(1 / math.sqrt(2), rel=1e-9)
    assert abs(cf.discrete_response(butterworth, np.array([0.0]), T)[0]) == pytest.approx(1.0)


def test_the_controller_filters_a_sine_as_the_chain_response():
    """Speed loop with Kp_vel = 1 A/(rad/s), no integral: current = F(speed command)."""
    settings = ControllerSettings(friction_torque=0.0, filters=(NOTCH, LOWPASS))
    p = c.parameter_vector(TunedParameters(1.0, 1.0, 0.0, 0.0, 0.01, 0.0), settings)
    for f in (40.0, 110.0, 600.0):
        s = c.initial_state(2)
        n = int(round(0.3 / T))  # the notch's transient (1/(zeta_p w_n) = 8 ms) dies out
        k = np.arange(n)
        out = np.empty(n)
        for i in k:
            s[c.SPEED_CMD] = math.sin(2 * math.pi * f * i * T)
            out[i] = c.speed_loop(p, s, i * T, 0.0)
        tail = k > n // 2
        basis = np.column_stack([np.sin(2 * np.pi * f * k * T), np.cos(2 * np.pi * f * k * T)])
        (a, b), *_ = np.linalg.lstsq(basis[tail], out[tail], rcond=None)
        expected = cf.chain_response([NOTCH, LOWPASS], np.array([f]), T)[0]
        assert a + 1j * b == pytest.approx(expected, abs=1e-6)


def test_filtered_loop_runs_the_same_on_both_paths(plant):
    grid = interpolate(
        sample_segments([Dwell(0.05), Ramp(0.01, 0.1, 0.2), Ramp(0.0, 0.1, 0.15)], 0.004),
        0.004,
        250e-6,
    )
    tuned = TunedParameters(66.7, 0.4, 0.008, 0.7, 0.008, 0.13)
    settings = ControllerSettings(filters=(NOTCH, LOWPASS))
    fast = run_axis(plant, grid, tuned, settings)
    slow = run_axis(plant, grid, tuned, settings, fast=False)
    assert np.max(np.abs(fast["x"] - slow["x"])) < 1e-9
    assert np.max(np.abs(fast["current"] - slow["current"])) < 1e-9
    unfiltered = run_axis(plant, grid, tuned, ControllerSettings())
    assert np.max(np.abs(fast["current"] - unfiltered["current"])) > 1e-4  # the chain acts


def test_filters_are_read_from_the_scenario(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(
        "reference: {segments: [{dwell: 0.1}]}\ncontroller:\n  settings:\n    filters:\n"
        "      - {type: notch, frequency_hz: 110, bandwidth_hz: 40, depth_db: -20}\n"
        "      - {type: lowpass, frequency_hz: 900}\n"
    )
    assert load_scenario(path).settings.filters == (NOTCH, LowPass(900.0))


@pytest.mark.parametrize(
    ("entries", "message"),
    [
        ("{type: notch, frequency_hz: 110}", r"filters\[0\]: notch: missing \['bandwidth_hz'"),
        ("{type: bandpass, frequency_hz: 110}", r"filters\[0\]: filter type: expected one of"),
        ("{type: notch, frequency_hz: 110, bandwidth_hz: 40, depth_db: 3}", "depth_db must be"),
        ("{type: lowpass, frequency_hz: 9000}", "below the speed loop's Nyquist frequency 8000"),
        ("{type: lowpass, frequency_hz: -5}", "frequency_hz must be a finite number > 0"),
        ("{type: lowpass, frequency_hz: 100, q: 1}", r"unknown key\(s\) \['q'\]"),
    ],
)
def test_bad_filters_are_refused_naming_the_entry(tmp_path, entries, message):
    path = tmp_path / "s.yaml"
    path.write_text(
        "reference: {segments: [{dwell: 0.1}]}\n"
        f"controller:\n  settings:\n    filters: [{entries}]\n"
    )
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(path)
    assert str(path) in str(info.value)


def test_no_filters_is_an_empty_chain():
    assert filters_section(Checker("x.yaml"), None, "filters") == ()
    assert (
        c.parameter_vector(TunedParameters(1, 1, 0, 0, 1, 0), ControllerSettings())[c.FILTER_COUNT]
        == 0.0
    )
