"""Where a diagnosis' time goes: phase totals, each fit's figures and the wall time of a batch on
idle workers; the judging replays answered by the cache as a fresh replay."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from twin_cosim.gap.data.context import DEFAULT_CONTEXT
from twin_cosim.gap.which.replay import FitTask, SimulateTask
from twin_cosim.gap.which.replay_pool import JudgingCache, PhaseTimes, ReplayPool, makespan
from twin_cosim.workers import BoundPool, SerialPool


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


def _pool(spec, cache: bool) -> ReplayPool:
    """A replay pool of one worker in this process over ``spec``, its judging cache or none."""
    judging = SimpleNamespace()  # the tasks alone never judge
    return ReplayPool(
        BoundPool(SerialPool(), spec),
        dict(spec.nominal),
        [],
        judging,
        0.03,
        cache=JudgingCache(spec.key, spec.training_in_judging()) if cache else None,
    )


def test_a_replay_asked_again_is_answered_by_the_cache_as_a_fresh_replay(small_spec):
    spec = small_spec()
    cached, fresh = _pool(spec, cache=True), _pool(spec, cache=False)
    try:
        level = {"stribeck_friction": 0.15, "stribeck_speed": 0.5}
        beyond = {**level, "stribeck_friction": -1.0}  # clipped to 0: the set of ``zero``
        zero = {**level, "stribeck_friction": 0.0}
        tasks = [SimulateTask(level), SimulateTask(beyond), SimulateTask(zero)]  # zero: again
        later = [
            SimulateTask(level, with_training=True),  # a time split: its training is judged
            SimulateTask(level),
        ]
        answers = cached.tasks("replays", tasks) + cached.tasks("replays", later)
        reference = fresh.tasks("replays", tasks + later)
        for got, expected in zip(answers, reference, strict=True):
            for record, fresh_record in zip(got.judging, expected.judging, strict=True):
                assert np.array_equal(record.to_numpy(), fresh_record.to_numpy())  # bit for bit
            assert (got.training is None) == (expected.training is None)
        training, fresh_training = answers[3].training[0], reference[3].training[0]
        assert np.array_equal(training.to_numpy(), fresh_training.to_numpy())
        phase = cached.times.as_dict()["replays"]
        assert (phase["tasks"], phase["replays"]) == (5, 5)
        assert (phase["replays_run"], phase["cache_hits"]) == (2, 3)
        assert fresh.times.as_dict()["replays"]["replays_run"] == 5
    finally:
        cached.pool.pool.close()
        fresh.pool.pool.close()


def test_each_fit_is_recorded_with_its_replays_and_times(small_spec):
    pool = _pool(small_spec(), cache=True)
    try:
        fits = pool.tasks(
            "fits", [FitTask("coulomb_change", {}, DEFAULT_CONTEXT), SimulateTask({})]
        )
        (record,) = pool.times.as_dict()["fits"]["fits"]  # the replay task is no fit
        assert record["fit"] == "coulomb_change" and record["replays"] == fits[0].replays
        assert record["replays_run"] + record["cache_hits"] == fits[0].replays + 1
        assert record["iterations"] == fits[0].iterations >= 1
        assert record["cpu_s"] > 0 and record["wall_s"] > 0
        total = pool.times.as_dict()["total"]
        assert total["replays_run"] == record["replays_run"] + 1 and "fits" not in total
    finally:
        pool.pool.pool.close()
