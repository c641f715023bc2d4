"""The optimize section: defaults, normalisation, and named errors.

Filter parameters tuned with the six; a campaign that starts from a controller set.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import scenario_text

from twin_cosim.controller_set import TABLE3, ControllerSet
from twin_cosim.current_filters import Notch
from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.config import DEFAULT_BOUNDS, load_config, within_bounds
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.scenario import ScenarioError, load_controller_set, load_scenario

BASE = (
    "reference:\n  segments:\n    - dwell: 0.1\n"
    "    - move: {to: 0.001, velocity: 0.01, acceleration: 0.1}\n"
)
REFERENCE1 = Path(__file__).resolve().parents[3] / "scenarios" / "reference1.yaml"


def config_of(tmp_path, optimize: str):
    path = tmp_path / "s.yaml"
    path.write_text(BASE + optimize)
    return load_config(load_scenario(path))


def test_defaults_hold_every_table3_set():
    config = load_config(load_scenario(REFERENCE1))
    assert config.iau_cap == 1.05
    assert all(within_bounds(config, tuned.as_array()) for tuned in TABLE3.values())
    assert config.window == (0.0, None)


def test_unit_mapping_round_trips(tmp_path):
    config = config_of(tmp_path, "optimize:\n  bounds: {Kp_pos: [10, 110]}\n")
    x = TABLE3["ft"].as_array()
    np.testing.assert_allclose(config.from_unit(config.to_unit(x)), x)
    assert config.from_unit(np.zeros(6))[0] == 10.0
    assert config.from_unit(np.ones(6))[1] == DEFAULT_BOUNDS["Kp_vel"][1]


@pytest.mark.parametrize(
    ("optimize", "message"),
    [
        ("optimize:\n  budget: 3\n", r"optimize: unknown key\(s\) \['budget'\]"),
        ("optimize:\n  bounds: {Kp: [1, 2]}\n", "unknown parameter 'Kp'"),
        ("optimize:\n  bounds: {Kp_pos: [5, 1]}\n", "expected low < high"),
        ("optimize:\n  bounds: {Kp_pos: [0, 1]}\n", "lower bound 0.0 allows invalid values"),
        ("optimize:\n  iau_cap: -1\n", "optimize.iau_cap: expected a number > 0"),
        ("optimize:\n  penalty_um: .inf\n", "optimize.penalty_um: expected a finite number"),
        ("optimize:\n  methods: {ce: 3}\n", "optimize.methods: expected a mapping"),
    ],
)
def test_mistakes_are_named(tmp_path, optimize, message):
    with pytest.raises(ScenarioError, match=message) as info:
        config_of(tmp_path, optimize)
    assert "s.yaml" in str(info.value)


def test_plant_samples_draw_within_the_intervals_and_the_tolerance():
    from twin_cosim.optimize.config import UncertaintySet, relative_ranges

    ranges = relative_ranges(
        {"backlash": (18e-6, 24e-6), "coulomb_asymmetry": (-0.01, 0.01)},
        {"backlash": 20e-6, "coulomb_asymmetry": 0.0},
    )
    assert ranges == {"backlash": pytest.approx((0.9, 1.2))}  # no relative range around 0
    samples = UncertaintySet(0.03, 200, 5, ("backlash", "torque_constant"), ranges).factors()
    assert samples[0] == {}
    backlash = np.array([s["backlash"] for s in samples[1:]])
    torque = np.array([s["torque_constant"] for s in samples[1:]])
    assert 0.9 <= backlash.min() < 0.92 and 1.18 < backlash.max() <= 1.2
    assert 0.97 <= torque.min() < 0.975 and 1.025 < torque.max() <= 1.03
    assert UncertaintySet(0.03, 200, 5, ("backlash",), ranges).factors() != samples


NOTCH = (
    "controller:\n  settings:\n"
    "    filters: [{type: notch, frequency_hz: 110, bandwidth_hz: 40, depth_db: -12}]\n"
)


def scenario_file(tmp_path, bounds: str, name="filtered.yaml"):
    path = tmp_path / name
    path.write_text(scenario_text(optimize=f"bounds: {{{bounds}}}") + NOTCH)
    return path


def test_filter_bounds_add_dimensions_after_the_six(tmp_path):
    path = scenario_file(tmp_path, "filter1.frequency_hz: [80, 160], filter1.depth_db: [-30, -3]")
    scenario = load_scenario(path)
    config = load_config(scenario)
    assert config.names[6:] == ("filter1.frequency_hz", "filter1.depth_db")
    assert list(config.start(scenario.tuned, scenario.settings)[6:]) == [110.0, -12.0]
    tuned, settings = config.candidate([*TABLE3["ga"].as_array(), 130.0, -20.0], scenario.settings)
    assert tuned == TABLE3["ga"] and settings.filters == (Notch(130.0, 40.0, -20.0),)
    assert list(config.as_dict()["bounds"])[6:] == list(config.names[6:])


def test_without_filter_bounds_the_six_alone(tmp_path):
    config = load_config(load_scenario(scenario_file(tmp_path, "Kp_pos: [20, 150]")))
    assert len(config.names) == 6 and config.filters == ()


@pytest.mark.parametrize(
    ("bounds", "message"),
    [
        ("filter2.frequency_hz: [80, 160]", "filters has 1 section"),
        ("filter1.q: [1, 2]", "a notch has the parameters"),
        ("filter1.frequency_hz: [80, 9000]", "below the speed loop's Nyquist frequency"),
        ("filter1.depth_db: [-20, 3]", "depth_db must be finite and <= 0"),
    ],
)
def test_bad_filter_bounds_are_named(tmp_path, bounds, message):
    path = scenario_file(tmp_path, bounds)
    with pytest.raises(ScenarioError, match=message) as info:
        load_config(load_scenario(path))
    assert str(path) in str(info.value) and "optimize.bounds" in str(info.value)


def test_a_campaign_tunes_the_notch_and_its_result_is_a_controller_set(tmp_path):
    path = scenario_file(tmp_path, "filter1.frequency_hz: [60, 200]")
    spec = CampaignSpec(str(path), "ce", seed=1, budget=40)
    result = run_campaign(AxisProblem.resolve(spec), tmp_path / "run", workers=1, progress=False)
    assert set(result.best_params) == {*TABLE3["ft"].as_dict(), "filter1.frequency_hz"}
    (notch,) = result.details["settings"]["filters"]
    assert notch["frequency_hz"] == result.best_params["filter1.frequency_hz"]
    best = load_controller_set(str(tmp_path / "run" / "result.json"))
    assert best.overrides["filters"][0].frequency_hz == notch["frequency_hz"]
    assert best.tuned.Kp_pos == result.best_params["Kp_pos"]


def test_a_campaign_starts_from_a_controller_set(tmp_path):
    path = tmp_path / "short.yaml"
    path.write_text(scenario_text())
    start = ControllerSet(TABLE3["ga"], {"filters": (Notch(110.0, 40.0, -12.0),)})
    set_file = tmp_path / "set.json"
    set_file.write_text(json.dumps(start.as_dict()))
    spec = CampaignSpec(str(path), "ce", seed=2, budget=20, start=str(set_file))
    result = run_campaign(AxisProblem.resolve(spec), tmp_path / "run", workers=1, progress=False)
    header = json.loads((tmp_path / "run" / "campaign.json").read_text())
    assert header["reference"]["params"] == TABLE3["ga"].as_dict()
    assert header["spec"]["start"] == str(set_file)
    assert result.fitness <= result.reference["E_pk_um"]  # the start is evaluated first


def test_a_campaign_stored_before_start_existed_resumes(tmp_path, twin_cli):
    path = tmp_path / "short.yaml"
    path.write_text(scenario_text())
    out = tmp_path / "old"
    run_campaign(
        AxisProblem.resolve(CampaignSpec(str(path), "ce", seed=2, budget=10)),
        out,
        workers=1,
        progress=False,
    )
    header = json.loads((out / "campaign.json").read_text())
    del header["spec"]["start"]
    (out / "campaign.json").write_text(json.dumps(header))
    result = twin_cli("optimize", str(path), "--resume", str(out), "--quiet", "--json")
    assert result.returncode == 0, result.stderr
