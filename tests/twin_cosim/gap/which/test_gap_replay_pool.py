"""Where a diagnosis' time goes: phase totals and the wall time of a batch on idle workers."""

from __future__ import annotations

from twin_cosim.gap.which.replay_pool import PhaseTimes, makespan


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
