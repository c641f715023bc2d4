"""The global search that starts a hypothesis' local fit, from its start values or from the
previous round's fit (no plant: a cost with a known narrow valley)."""

from __future__ import annotations

import numpy as np

from twin_cosim.gap.replay import (
    GLOBAL_GENERATIONS,
    GLOBAL_POPULATION_PER_PARAMETER,
    WARM_GENERATIONS,
    Replayer,
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
