"""Swaps of an accepted effect for a rival of its round (gap/swaps.py), on a stand-in selection
whose held-out residual is a given pattern per parameter set (noise at the floors is 1)."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.calibration import CalibrationBasis, normalised_vector
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.replay import FitResult, FitTask, JointFitTask, Replays, SimulateTask
from twin_cosim.gap.which.rounds import Accepted, Candidate, Swap
from twin_cosim.gap.which.swaps import rivals, swap

SAMPLES = 2000
PATTERN = np.sin(np.linspace(0.0, 40.0, SAMPLES))  # a structured residual, RMS 0.71

LIBRARY = {
    name: SimpleNamespace(kind="continuous", sets={key: 0}, parameters=(None,))
    for name, key in (
        ("backlash_change", "backlash"),
        ("stiffness_change", "resonance_frequency"),
        ("inertia_change", "load_inertia"),
        ("current_lag", "current_time_constant"),
    )
}


def _residuals(position: np.ndarray) -> Residuals:
    zeros = np.zeros(SAMPLES)
    return Residuals(np.arange(SAMPLES) * 0.005, position, zeros, zeros, zeros, zeros, zeros)


class _Judging:
    """Held-out runs of 10 s whose position residual is the replay's own (floors of 1)."""

    floors = SimpleNamespace(sigma_position_m=1.0, sigma_current=1.0)
    duration_s = 10.0

    def residuals(self, replays: Replays) -> Residuals:
        return _residuals(replays.judging[0])

    def vector(self, res: Residuals) -> np.ndarray:
        return normalised_vector(res, 1.0, 1.0)


@dataclass
class StandIn:
    """A selection whose replay of a parameter set has the residual ``gap(overrides)``; a
    rival's fit sets ``fitted[name]`` on top of its base, a joint refit ``joint(overrides)``."""

    gap: object
    fitted: dict[str, dict[str, float]]
    joint: object = field(default_factory=lambda: lambda overrides: overrides)
    library: dict = field(default_factory=lambda: LIBRARY)
    judging: _Judging = field(default_factory=_Judging)
    settings: DiagnosisSettings = field(default_factory=DiagnosisSettings)
    train_seconds: float = 10.0
    asked: list = field(default_factory=list)

    def tasks(self, phase: str, tasks: list) -> list:
        self.asked.extend(tasks)
        results = []
        for task in tasks:
            if isinstance(task, FitTask):
                values = self.fitted[task.hypothesis]
                overrides = {**task.base, **values}
                results.append(FitResult(task.hypothesis, values, overrides, 1.0, 1, ""))
            elif isinstance(task, JointFitTask):
                sequential = {}
                for name, start in zip(task.hypotheses, task.start, strict=True):
                    sequential[next(iter(self.library[name].sets))] = start[0]
                results.append(FitResult("+", {}, self.joint(sequential), 1.0, 1, ""))
            else:
                assert isinstance(task, SimulateTask) and task.with_training
                residual = self.gap(task.overrides)
                results.append(Replays([residual], [residual]))
        return results

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        return CalibrationBasis([], np.zeros((2 * SAMPLES, 0)))

    def refit_task(self, accepted: list[Accepted]) -> JointFitTask:
        return JointFitTask(
            tuple(a.name for a in accepted),
            tuple(a.values for a in accepted),
            tuple(a.context for a in accepted),
        )

    def size_above_tolerance(self, hypothesis, values, base) -> bool:
        return True


def _candidate(name: str, passes: bool, value: float) -> Candidate:
    key = next(iter(LIBRARY[name].sets))
    fit = FitResult(name, {key: value}, {key: value}, 1.0, 1, "")
    return Candidate(fit, 1, 0.0, passes=passes)


def _rounds() -> list:
    first = SimpleNamespace(
        candidates=[
            _candidate("backlash_change", True, 8e-6),
            _candidate("stiffness_change", True, 60.0),
            _candidate("inertia_change", False, 5e-4),
        ]
    )
    second = SimpleNamespace(candidates=[_candidate("current_lag", True, 2e-4)])
    return [first, second]


def _accepted() -> list[Accepted]:
    return [
        Accepted(["backlash_change"], (8e-6,), {"motor_order": 6.0}, 1),
        Accepted(["current_lag"], (2e-4,), {"motor_order": 6.0}, 2),
    ]


BASE = {"backlash": 8e-6, "current_time_constant": 2e-4}


def _gap(swapped_left: float):
    """Residual RMS 4 with the backlash, ``swapped_left`` with the stiffness instead."""

    def gap(overrides: dict[str, float]) -> np.ndarray:
        size = swapped_left if "resonance_frequency" in overrides else 4.0
        return 2.0 * size * PATTERN  # normalised RMS: size

    return gap


def test_rivals_are_the_other_passing_hypotheses_of_the_effects_round():
    found = rivals(_rounds(), _accepted(), set())
    assert [(j, c.name) for j, c in found] == [(0, "stiffness_change")]
    assert rivals(_rounds(), _accepted(), {"stiffness_change"}) == []  # never swapped back in
    unknown = [Accepted(["backlash_change"], (8e-6,), {}, 0)]
    assert rivals(_rounds(), unknown, set()) == []


def test_a_rival_that_leaves_much_less_replaces_its_effect():
    selection = StandIn(_gap(1.0), {"stiffness_change": {"resonance_frequency": 60.0}})
    accepted, records = _accepted(), []
    replays = Replays([_gap(1.0)(BASE)], [_gap(1.0)(BASE)])
    result = swap(selection, _rounds(), accepted, BASE, replays, records)
    assert result is not None
    base, after = result
    assert base == {"current_time_constant": 2e-4, "resonance_frequency": 60.0}
    assert np.allclose(after.judging[0], _gap(1.0)(base))
    assert [a.name for a in accepted] == ["stiffness_change", "current_lag"]
    assert accepted[0].round == 1 and accepted[0].context == {"motor_order": 6.0}
    assert [(r.removed, r.candidate.name, r.kept) for r in records] == [
        ("backlash_change", "stiffness_change", True)
    ]
    assert records[0].candidate.passes and records[0].candidate.evidence_z > 100.0
    fit = next(t for t in selection.asked if isinstance(t, FitTask))
    assert "backlash" not in fit.base and fit.base["current_time_constant"] == 2e-4
    assert fit.start == (60.0,)  # from the rival's fit of its round
    joint = next(t for t in selection.asked if isinstance(t, JointFitTask))
    assert joint.hypotheses == ("stiffness_change", "current_lag")


def test_the_joint_refit_of_the_swapped_model_is_judged_when_it_leaves_less():
    def joint(sequential: dict[str, float]) -> dict[str, float]:
        return {**sequential, "resonance_frequency": 58.0, "refitted": 1.0}

    def gap(overrides: dict[str, float]) -> np.ndarray:
        if "refitted" in overrides:
            return 2.0 * PATTERN  # norm 1
        return (3.0 if "resonance_frequency" in overrides else 4.0) * 2.0 * PATTERN

    selection = StandIn(gap, {"stiffness_change": {"resonance_frequency": 60.0}}, joint)
    replays = Replays([gap(BASE)], [gap(BASE)])
    base, _ = swap(selection, _rounds(), _accepted(), BASE, replays, [])
    assert base["refitted"] == 1.0


def test_no_swap_when_the_rival_does_not_fit_better_beyond_the_noise():
    selection = StandIn(_gap(4.0), {"stiffness_change": {"resonance_frequency": 60.0}})
    accepted, records = _accepted(), []
    replays = Replays([_gap(4.0)(BASE)], [_gap(4.0)(BASE)])
    assert swap(selection, _rounds(), accepted, BASE, replays, records) is None
    assert [a.name for a in accepted] == ["backlash_change", "current_lag"]
    assert len(records) == 1 and not records[0].kept and not records[0].candidate.passes


def test_nothing_is_fitted_without_rivals():
    selection = StandIn(_gap(1.0), {})
    records: list[Swap] = []
    replays = Replays([_gap(1.0)(BASE)], [_gap(1.0)(BASE)])
    accepted = _accepted()[1:]
    assert swap(selection, _rounds(), accepted, BASE, replays, records) is None
    assert selection.asked == [] and records == []
