"""Replays and fits on a worker: nothing a fit derives from data reaches the FMU outside the
variable table's ranges; the global search that starts a hypothesis' local fit, from its start
values or from the previous round's fit, and the profile over a shape parameter that starts a
cold refit (no plant: costs with a known narrow valley)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from twin_cosim.gap.synth import DEFAULT_CONTEXT
from twin_cosim.gap.which.replay import (
    GLOBAL_GENERATIONS,
    GLOBAL_POPULATION_PER_PARAMETER,
    PROFILE_EVALUATIONS,
    PROFILE_POINTS,
    WARM_GENERATIONS,
    FitTask,
    Replayer,
    UncertaintyTask,
    bounded,
    clipped,
    linearised_uncertainty,
    profile_start,
    shape_index,
)
from twin_cosim.plant_model import plant_model

BY_NAME = {h.name: h for h in plant_model("drive2mass").hypotheses}


def test_position_friction_at_its_fit_bounds_is_clipped_to_the_fmu_range(plant):
    """cos and sin parts at 0.9 each give an amplitude of 1.27 > the FMU's 0.99."""
    from twin_cosim.gap.data.context import variable_ranges

    ranges = variable_ranges(plant)
    hypothesis = BY_NAME["position_friction"]
    overrides = hypothesis.to_plant(np.array([0.9, 0.9]), {}, DEFAULT_CONTEXT)
    assert overrides["position_friction_amplitude"] == pytest.approx(np.hypot(0.9, 0.9))
    safe = clipped(overrides, ranges)
    assert safe["position_friction_amplitude"] == ranges["position_friction_amplitude"][1]
    plant.start_run(safe)  # accepted by the FMU


def test_bounds_of_fmu_parameters_come_from_the_variable_table():
    ranges = {"stribeck_friction": (0.0, 1.5), "stribeck_speed": (0.1, 100.0)}
    narrowed = bounded(BY_NAME["stribeck"], ranges)
    friction, speed = narrowed.parameters
    assert (friction.lower, friction.upper) == (0.0, 1.5)
    assert (speed.lower, speed.upper) == (0.1, 2.0)
    assert speed.lower <= speed.initial <= speed.upper


BACKLASH = {h.name: h for h in plant_model("drive2mass").hypotheses}["backlash_change"]
TRUE_CHANGE = 6e-6  # m


def valley(u: np.ndarray) -> np.ndarray:
    """A residual whose cost has one narrow valley at the true backlash change (width 0.5 um),
    flat elsewhere: a local fit from far away does not see it."""
    change = BACKLASH.from_unit(u)[0]
    return np.array([1.0 - np.exp(-(((change - TRUE_CHANGE) / 0.5e-6) ** 2))])


def test_cold_start_searches_the_whole_range_within_its_budget():
    start, evaluations = Replayer._coarse_start(BACKLASH, valley, None)
    population = GLOBAL_POPULATION_PER_PARAMETER * len(BACKLASH.parameters)
    assert evaluations <= population * (GLOBAL_GENERATIONS + 1)
    assert start.shape == (1,) and 0.0 <= start[0] <= 1.0


def test_warm_start_keeps_the_previous_valley_at_a_fraction_of_the_cost():
    previous = (TRUE_CHANGE + 0.1e-6,)  # the round before found the valley
    start, evaluations = Replayer._coarse_start(BACKLASH, valley, previous)
    population = GLOBAL_POPULATION_PER_PARAMETER * len(BACKLASH.parameters)
    assert evaluations <= population * (WARM_GENERATIONS + 1)
    assert WARM_GENERATIONS < GLOBAL_GENERATIONS
    assert abs(BACKLASH.from_unit(start)[0] - TRUE_CHANGE) <= 0.1e-6 + 1e-12
    assert valley(start)[0] < 0.05


LIBRARY = {h.name: h for h in plant_model("drive2mass").hypotheses}
STRIBECK = LIBRARY["stribeck"]
TRUE_LEVEL, TRUE_SPEED = 0.147, 0.615  # N.m, rad/s


def area_valley(u: np.ndarray) -> np.ndarray:
    """A Stribeck-like training residual: the area under the curve (level x speed) is what
    most of the data see, linear in the level; the true width shows in a narrow valley
    (0.3 in log speed), flat elsewhere: every curve of the right area is a local minimum."""
    level, speed = STRIBECK.from_unit(u)
    area = 30.0 * (level * speed - TRUE_LEVEL * TRUE_SPEED)
    width = 1.0 - np.exp(-((np.log(speed / TRUE_SPEED) / 0.3) ** 2))
    return np.array([area, width])


def test_shape_parameter_is_the_log_one_of_two():
    assert shape_index(STRIBECK) == 1
    assert shape_index(LIBRARY["backlash_change"]) is None  # one parameter
    assert shape_index(LIBRARY["torque_ripple"]) is None  # two, neither on a log scale
    assert shape_index(LIBRARY["pitch_error"]) is None  # three


def test_profile_over_the_shape_finds_the_narrow_valley_of_the_true_width():
    start, evaluations = profile_start(STRIBECK, area_valley)
    spacing = 1.0 / PROFILE_POINTS
    assert abs(start[1] - STRIBECK.parameters[1].to_unit(TRUE_SPEED)) <= spacing / 2
    level, speed = STRIBECK.from_unit(start)
    assert abs(level * speed - TRUE_LEVEL * TRUE_SPEED) < 0.01 * TRUE_LEVEL * TRUE_SPEED
    assert np.mean(area_valley(start) ** 2) < 0.1 * np.mean(area_valley(np.array([0.2, 0.9])) ** 2)
    # each shape value: the level's evaluations and as many one-column Jacobians at most
    assert evaluations <= 2 * PROFILE_EVALUATIONS * PROFILE_POINTS


# --- the worker's cache of training residuals, by the parameter set a replay runs with


def test_a_parameter_set_asked_again_is_answered_by_the_cache_as_a_fresh_replay(small_spec):
    cached, fresh = Replayer(small_spec()), Replayer(small_spec(0))
    try:
        guess = {"stribeck_friction": 0.15, "stribeck_speed": 0.5}
        first = cached.training_residual(guess)
        assert (cached.replays_run, cached.cache_hits) == (1, 0)
        first[:] = 0.0  # what a caller does with its copy does not reach the cache
        again = cached.training_residual(guess)
        assert (cached.replays_run, cached.cache_hits) == (1, 1)
        assert np.array_equal(again, fresh.training_residual(guess))  # bit for bit
        assert np.any(again != 0.0)
        # a value beyond its range runs clipped: the same parameter set, the same replay
        low = cached.spec.ranges["stribeck_friction"][0]
        beyond = cached.training_residual({**guess, "stribeck_friction": low - 1.0})
        at_bound = cached.training_residual({**guess, "stribeck_friction": low})
        assert (cached.replays_run, cached.cache_hits) == (2, 2)
        assert np.array_equal(beyond, at_bound)
        assert fresh.cache_hits == 0 and not fresh.residuals
    finally:
        cached.close()
        fresh.close()


def test_the_cache_keeps_the_latest_parameter_sets(small_spec):
    replayer = Replayer(small_spec())
    residual_bytes = replayer.training_residual({}).nbytes
    replayer.close()
    replayer = Replayer(small_spec(cache_bytes=2 * residual_bytes))  # two residuals
    try:
        for level in (0.1, 0.2, 0.3):
            replayer.training_residual({"stribeck_friction": level})
        assert len(replayer.residuals) == 2
        replayer.training_residual({"stribeck_friction": 0.1})  # dropped: replayed again
        assert (replayer.replays_run, replayer.cache_hits) == (4, 0)
        replayer.training_residual({"stribeck_friction": 0.3})
        assert replayer.cache_hits == 1
    finally:
        replayer.close()


def test_a_fit_reports_its_iterations_and_search_and_its_cache_hits(small_spec):
    replayer = Replayer(small_spec())
    try:
        timed = replayer(FitTask("coulomb_change", {}, DEFAULT_CONTEXT))
        fit = timed.result
        # the global search's last population member is where least squares starts: a hit
        assert timed.cache_hits >= 1
        assert timed.replays_run + timed.cache_hits == fit.replays + 1  # + the base model's
        assert fit.search_replays > 0 and fit.iterations >= 1
        assert fit.replays > fit.search_replays + fit.iterations  # each iteration: a Jacobian
        assert timed.wall_s > 0 and timed.cpu_s > 0
    finally:
        replayer.close()


def test_the_linearised_uncertainty_of_a_level_is_one_over_its_sensitivity():
    """A residual linear in the Coulomb level, r = g (F_c - F_0) + e with RMS(e) = 1: the
    information of the level on the unit scale (width W of its bounds) is n_eff (g W)^2, so its
    deviation is 1 / (g W sqrt(n_eff)), n_eff = 2 s / 10 ms for two signals over 1 s; its FMU
    interval is the fitted value +- 1.96 of it. Every residual is asked for in one batch."""
    hypothesis = BY_NAME["coulomb_change"]
    nominal, fitted = {"coulomb_friction": 0.5}, 0.1  # N.m
    t = np.linspace(0.0, 1.0, 4001)  # s
    spec = SimpleNamespace(nominal=nominal, ranges={}, training=SimpleNamespace(t=[t]))
    noise = np.random.default_rng(1).choice([-1.0, 1.0], 2 * t.size)  # RMS 1 exactly
    g = 50.0  # residual per N.m
    batches = []

    def residuals(sets: list[dict[str, float]]) -> list[np.ndarray]:
        batches.append(len(sets))
        return [g * (s["coulomb_friction"] - 0.5 - fitted) + noise for s in sets]

    task = UncertaintyTask({}, ("coulomb_change",), ((fitted,),), ({},), (), 0.03)
    found = linearised_uncertainty(task, BY_NAME, spec, residuals)
    width = hypothesis.parameters[0].upper - hypothesis.parameters[0].lower  # N.m
    n_eff = 2.0 * 1.0 / 0.01
    deviation = 1.0 / (g * width * np.sqrt(n_eff))
    assert batches == [3]  # the model and both sides of its one column, at once
    assert found.names == ("coulomb_change.delta_coulomb",)
    assert found.deviation[0] == pytest.approx(deviation, rel=1e-9)
    low, high = found.intervals["coulomb_friction"]
    spread = deviation * width  # N.m
    assert low == pytest.approx(0.6 - 1.96 * spread, abs=0.2 * spread)
    assert high == pytest.approx(0.6 + 1.96 * spread, abs=0.2 * spread)


def _asked_sets(task: UncertaintyTask, nominal: dict[str, float]) -> list[dict[str, float]]:
    """The parameter sets the uncertainty of ``task`` asks residuals of (over 1 s of training,
    every residual the same), in their order."""
    t = np.linspace(0.0, 1.0, 101)  # s
    spec = SimpleNamespace(nominal=nominal, ranges={}, training=SimpleNamespace(t=[t]))
    asked: list[dict[str, float]] = []

    def residuals(sets: list[dict[str, float]]) -> list[np.ndarray]:
        asked.extend(sets)
        return [np.ones(2 * t.size) for _ in sets]

    linearised_uncertainty(task, BY_NAME, spec, residuals)
    return asked


def test_the_uncertainty_asks_for_the_models_own_sets_where_nothing_of_it_moves():
    """The model's residual and its calibrated columns run with the effect's fitted values
    exactly (the sets of its replays and calibration directions, which a cache answers), not
    their round trip through the log unit scale; only the effect's own columns move them."""
    stribeck = BY_NAME["stribeck"]
    fitted = (0.1994052256439948, 0.3995573699235268)  # N.m, rad/s
    speed = stribeck.parameters[1]
    assert speed.from_unit(speed.to_unit(fitted[1])) != fitted[1]  # not exact on the way back
    nominal = {"coulomb_friction": 0.6, "motor_inertia": 3e-4}  # N.m, kg.m^2
    model = stribeck.to_plant(np.array(fitted), nominal, dict(DEFAULT_CONTEXT))
    task = UncertaintyTask(
        model, ("stribeck",), (fitted,), (dict(DEFAULT_CONTEXT),), ("motor_inertia",), 0.03
    )
    asked = _asked_sets(task, nominal)
    assert len(asked) == 1 + 2 * 3  # the model, both sides of two effect columns and one more
    ran = [{**nominal, **s} for s in asked]  # the parameter sets the replays run with
    assert ran[0] == {**nominal, **model}
    assert ran[5:] == [
        {**nominal, **model, "motor_inertia": 3e-4 * (1 + a * 0.03)} for a in (1, -1)
    ]
    assert all(s["stribeck_speed"] != fitted[1] for s in asked[3:5])  # the speed's column


def test_the_uncertainty_is_taken_at_the_model_a_joint_refit_left():
    """A Coulomb change on top of a Coulomb level the joint refit moved by +2 %: the model's
    residual is asked at the model's own level, and the level's calibration column moves the
    level beneath the change, not the nominal one."""
    moved, delta = 0.6 * 1.02, 0.1  # N.m: the refit's level beneath, the fitted change
    task = UncertaintyTask(
        {"coulomb_friction": moved + delta},
        ("coulomb_change",),
        ((delta,),),
        (dict(DEFAULT_CONTEXT),),
        ("coulomb_friction",),
        0.03,
    )
    levels = [s["coulomb_friction"] for s in _asked_sets(task, {"coulomb_friction": 0.6})]
    assert levels[0] == pytest.approx(moved + delta, rel=1e-14)  # the model, not 0.6 + 0.1
    assert levels[3:] == pytest.approx([moved * 1.03 + delta, moved * 0.97 + delta], rel=1e-14)
