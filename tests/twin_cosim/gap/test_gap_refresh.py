"""Accepted effects refitted from a cold start on top of the others (gap/refresh.py), on a
stand-in selection whose held-out residual left is a given number per parameter set."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from twin_cosim.gap.refresh import refresh
from twin_cosim.gap.replay import FitResult, FitTask, Replays, SimulateTask
from twin_cosim.gap.rounds import Accepted

LIBRARY = {
    "stribeck": SimpleNamespace(
        kind="continuous", sets={"stribeck_friction": 0, "stribeck_speed": 0}
    ),
    "inertia_change": SimpleNamespace(kind="continuous", sets={"motor_inertia": 0}),
    "dead_time": SimpleNamespace(kind="scan", sets={"dead_time_steps": 0}),
}


@dataclass
class StandIn:
    """Refits return ``refits[name]`` on top of their base; ``left`` is ``lefts[overrides]``."""

    refits: dict[str, dict[str, float]]
    lefts: dict[tuple, float]
    library: dict = field(default_factory=lambda: LIBRARY)
    asked: list = field(default_factory=list)

    def tasks(self, phase: str, tasks: list) -> list:
        self.asked.extend(tasks)
        results = []
        for task in tasks:
            if isinstance(task, FitTask):
                values = self.refits[task.hypothesis]
                results.append(
                    FitResult(task.hypothesis, values, {**task.base, **values}, 0.0, 1, "")
                )
            else:
                assert isinstance(task, SimulateTask) and task.with_training
                results.append(Replays([task.overrides], [task.overrides]))
        return results

    def left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        return np.array([self.lefts[tuple(sorted(overrides.items()))]])


BASE = {"stribeck_friction": 0.107, "stribeck_speed": 0.87, "motor_inertia": 3.3e-4}


def _accepted() -> list[Accepted]:
    return [
        Accepted(["stribeck"], (0.107, 0.87), {}),
        Accepted(["inertia_change"], (0.15,), {}),
        Accepted(["dead_time"], (3.0,), {}),
    ]


def _key(overrides: dict[str, float]) -> tuple:
    return tuple(sorted(overrides.items()))


def test_the_best_cold_refit_replaces_its_effect_when_it_leaves_less():
    stribeck = {"stribeck_friction": 0.16, "stribeck_speed": 0.58}
    inertia = {"motor_inertia": 3.4e-4}
    lefts = {_key(BASE): 3.8, _key({**BASE, **stribeck}): 1.0, _key({**BASE, **inertia}): 3.5}
    selection = StandIn({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    accepted = _accepted()
    refitted = refresh(selection, accepted, BASE, Replays([BASE], [BASE]))
    assert refitted is not None
    base, replays = refitted
    assert base == {**BASE, **stribeck}
    assert replays.judging == [base]
    assert accepted[0].values == (0.16, 0.58)
    assert accepted[1].values == (0.15,)  # the other refit left more: unchanged
    fits = [t for t in selection.asked if isinstance(t, FitTask)]
    assert [t.hypothesis for t in fits] == ["stribeck", "inertia_change"]  # no scan refitted
    assert fits[0].start is None  # a cold start: the full global search
    assert "stribeck_friction" not in fits[0].base and "motor_inertia" in fits[0].base
    assert "motor_inertia" not in fits[1].base and "stribeck_speed" in fits[1].base


def test_the_model_stays_as_it_is_when_no_refit_leaves_less():
    stribeck = {"stribeck_friction": 0.05, "stribeck_speed": 1.9}
    inertia = {"motor_inertia": 3.4e-4}
    lefts = {_key(BASE): 1.0, _key({**BASE, **stribeck}): 1.2, _key({**BASE, **inertia}): 1.0}
    selection = StandIn({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    accepted = _accepted()
    assert refresh(selection, accepted, BASE, Replays([BASE], [BASE])) is None
    assert [a.values for a in accepted] == [a.values for a in _accepted()]


def test_a_single_effect_is_not_refitted():
    selection = StandIn({}, {})
    assert refresh(selection, _accepted()[:1], BASE, Replays([BASE], [BASE])) is None
    assert selection.asked == []
