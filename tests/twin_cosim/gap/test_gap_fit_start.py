"""The global search that starts a hypothesis' local fit, from its start values or from the
previous round's fit, and the profile over a shape parameter that starts a cold refit (no
plant: costs with a known narrow valley)."""

from __future__ import annotations

import numpy as np

from twin_cosim.gap.replay import (
    GLOBAL_GENERATIONS,
    GLOBAL_POPULATION_PER_PARAMETER,
    PROFILE_EVALUATIONS,
    PROFILE_POINTS,
    WARM_GENERATIONS,
    Replayer,
    profile_start,
    shape_index,
)
from twin_cosim.gap.timing import PhaseTimes, makespan
from twin_cosim.plant_model import plant_model

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


def test_phase_times_add_up():
    times = PhaseTimes()
    with times.timed("fits", tasks=3) as phase:
        phase.replays += 30
        phase.cpu_s += 6.0
    with times.timed("fits", tasks=1) as phase:
        phase.replays += 5
    with times.timed("replays", tasks=2) as phase:
        phase.replays += 2
        phase.cpu_s += 1.0
    table = times.as_dict()
    assert table["fits"]["tasks"] == 4 and table["fits"]["replays"] == 35
    assert table["total"]["replays"] == 37 and table["total"]["tasks"] == 6
    assert table["total"]["cpu_s"] == 7.0
    assert table["total"]["wall_s"] >= table["fits"]["wall_s"] >= 0.0


def test_makespan_of_tasks_in_order_on_free_workers():
    assert makespan([], 2) == 0.0
    assert makespan([3.0, 1.0, 1.0, 1.0], 2) == 3.0  # the short ones share the second worker
    assert makespan([1.0, 1.0, 3.0], 2) == 4.0  # the long one last waits for a free worker
    assert makespan([2.0, 2.0], 1) == 4.0


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
