"""Accepted effects refitted from a cold start on top of the others (gap/refresh.py), on a
stand-in selection whose held-out residual left is a given vector per parameter set."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from twin_cosim.gap.which.refresh import refresh
from twin_cosim.gap.which.replay import FitResult, FitTask, Replays, SimulateTask
from twin_cosim.gap.which.rounds import Accepted
from twin_cosim.plant_model import plant_model

CARD = {h.name: h for h in plant_model("drive2mass").hypotheses}
LIBRARY = {
    "stribeck": SimpleNamespace(
        kind="continuous",
        sets={"stribeck_friction": 0, "stribeck_speed": 0},
        parameters=CARD["stribeck"].parameters,  # a level and a shape (log) parameter
    ),
    "inertia_change": SimpleNamespace(
        kind="continuous", sets={"motor_inertia": 0}, parameters=CARD["inertia_change"].parameters
    ),
    "dead_time": SimpleNamespace(
        kind="scan", sets={"dead_time_steps": 0}, parameters=CARD["dead_time"].parameters
    ),
}


@dataclass
class StandIn:
    """Refits return ``refits[(name, profile)]`` or else ``refits[name]`` on top of their base;
    ``left`` is ``lefts[overrides]``
    (a number: that many times a unit vector of 100 samples; or the vector itself). The
    held-out data last 1 s (100 independent samples per signal)."""

    refits: dict[str | tuple[str, bool], dict[str, float]]
    lefts: dict[tuple, float | np.ndarray]
    library: dict = field(default_factory=lambda: LIBRARY)
    asked: list = field(default_factory=list)
    judging: SimpleNamespace = field(default_factory=lambda: SimpleNamespace(duration_s=1.0))
    settings: SimpleNamespace = field(
        default_factory=lambda: SimpleNamespace(acceptance_level=0.01)
    )

    def tasks(self, phase: str, tasks: list) -> list:
        self.asked.extend(tasks)
        results = []
        for task in tasks:
            if isinstance(task, FitTask):
                values = self.refits.get((task.hypothesis, task.profile))
                values = values or self.refits[task.hypothesis]
                results.append(
                    FitResult(task.hypothesis, values, {**task.base, **values}, 0.0, 1, "")
                )
            else:
                assert isinstance(task, SimulateTask) and task.with_training
                results.append(Replays([task.overrides], [task.overrides]))
        return results

    def left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        left = self.lefts[tuple(sorted(overrides.items()))]
        return left if isinstance(left, np.ndarray) else np.full(100, left / 10.0)


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
    base, replays, record = refitted
    assert base == {**BASE, **stribeck}
    assert replays.judging == [base]
    assert accepted[0].values == (0.16, 0.58)
    assert accepted[1].values == (0.15,)  # the other refit left more: unchanged
    fits = [t for t in selection.asked if isinstance(t, FitTask)]
    # no scan refitted; the Stribeck curve twice: the global search and the profile over its speed
    assert [(t.hypothesis, t.profile) for t in fits] == [
        ("stribeck", False),
        ("inertia_change", False),
        ("stribeck", True),
    ]
    assert all(t.start is None for t in fits)  # cold starts
    assert "stribeck_friction" not in fits[0].base and "motor_inertia" in fits[0].base
    assert "motor_inertia" not in fits[1].base and "stribeck_speed" in fits[1].base
    assert record.effect == "stribeck"
    assert record.values_before == (0.107, 0.87) and record.values_after == (0.16, 0.58)
    assert (record.left_before, record.left_after) == (3.8, 1.0)
    # energy left 14.44 -> 1: all of the excess; z = 13.44 / (2 * 2.8 / sqrt(200)) = 33.9
    assert record.excess_share == 1.0
    assert abs(record.evidence_z - 13.44 / (2 * 2.8 / np.sqrt(200))) < 1e-9
    assert abs(record.critical_z - 2.713) < 1e-3  # level 0.01 shared by the three refits tried
    assert record.significant


def test_the_profile_refit_replaces_the_curve_when_it_leaves_less_than_the_global_search():
    """The global search stops in the wide valley (the area right, the width wrong); the
    profile over the speed finds the narrow one."""
    wide = {"stribeck_friction": 0.116, "stribeck_speed": 0.91}
    narrow = {"stribeck_friction": 0.149, "stribeck_speed": 0.615}
    inertia = {"motor_inertia": 3.4e-4}
    lefts = {
        _key(BASE): 3.4,
        _key({**BASE, **wide}): 3.3,
        _key({**BASE, **narrow}): 0.6,
        _key({**BASE, **inertia}): 3.5,
    }
    refits = {("stribeck", False): wide, ("stribeck", True): narrow, "inertia_change": inertia}
    selection = StandIn(refits, lefts)
    accepted = _accepted()
    base, _, record = refresh(selection, accepted, BASE, Replays([BASE], [BASE]))
    assert base == {**BASE, **narrow}
    assert accepted[0].values == (0.149, 0.615) and record.values_after == (0.149, 0.615)
    assert record.left_after == 0.6 and record.significant


def test_a_refit_within_the_noise_replaces_its_effect_but_is_not_significant():
    """A refit that leaves a little less, as noise could, is taken, and judged no gain."""
    rng = np.random.default_rng(0)
    before = 1.33 * np.ones(100) / 10.0
    after = before - 0.002 * rng.standard_normal(100)  # leaves a little less, within the noise
    after *= 0.999 * np.linalg.norm(before) / np.linalg.norm(after)
    stribeck = {"stribeck_friction": 0.11, "stribeck_speed": 0.86}
    inertia = {"motor_inertia": 3.4e-4}
    lefts = {
        _key(BASE): before,
        _key({**BASE, **stribeck}): after,
        _key({**BASE, **inertia}): 1.4,
    }
    selection = StandIn({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    refitted = refresh(selection, _accepted(), BASE, Replays([BASE], [BASE]))
    assert refitted is not None
    base, _, record = refitted
    assert base == {**BASE, **stribeck}
    assert record.left_after < record.left_before
    assert record.evidence_z < record.critical_z
    assert not record.significant


def test_a_refit_needs_its_fair_share_of_the_excess_to_be_significant():
    """A gain far beyond the noise that removes under 1/12 of the excess energy is no gain."""
    before = np.zeros(10_000)
    before[0] = 10.0  # energy 100, excess 99
    after = before.copy()
    after[0] = np.sqrt(100.0 - 5.0)  # removes 5 of the 99: z large, share 0.05 < 1/12
    stribeck = {"stribeck_friction": 0.11, "stribeck_speed": 0.86}
    library = {**LIBRARY, **{f"other_{k}": LIBRARY["dead_time"] for k in range(9)}}
    selection = StandIn(
        {"stribeck": stribeck, "inertia_change": {"motor_inertia": 3.4e-4}},
        {
            _key(BASE): before,
            _key({**BASE, **stribeck}): after,
            _key({**BASE, "motor_inertia": 3.4e-4}): 11.0,
        },
        library=library,
    )
    _, _, record = refresh(selection, _accepted(), BASE, Replays([BASE], [BASE]))
    assert record.evidence_z > record.critical_z
    assert abs(record.excess_share - 5.0 / 99.0) < 1e-12
    assert record.fair_share == 1.0 / 12.0
    assert not record.significant


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
