"""The selector's records and its steps: a round's candidates judged with the calibration
corrections replayed, the joint screen of a later round, swaps of an accepted effect for a
rival of its round, and cold refits of the accepted effects, each on a stand-in replay pool
whose held-out residual is a given pattern or vector per parameter set (noise at the floors is
1)."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.evidence import CalibrationBasis, CalibrationFloor
from twin_cosim.gap.floors.noise import Floors
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.acceptance import (
    Candidate,
    Gain,
    JointCandidate,
    Judgement,
    Judging,
    Pair,
    judge,
)
from twin_cosim.gap.which.replay import FitResult, FitTask, JointFitTask, Replays, SimulateTask
from twin_cosim.gap.which.selector import (
    Accepted,
    Round,
    Selector,
    Swap,
    bic,
    correlation,
    refitted,
    rivals,
)
from twin_cosim.plant_model import plant_model

NO_REPLAYS = Replays(None, [])


def _judged(passes: bool) -> Judgement:
    """A judgement that passes every test, or fails them all."""
    gain = Gain(10.0, 3.0, 0.5, 1.0 / 12.0) if passes else Gain(0.0, 3.0, 0.0, 1.0 / 12.0)
    return Judgement(1.0, 0.5 if passes else 0.0, 0.5, 1.0, gain, True, True, 1.0, 0.1, np.zeros(0))


class _HeldOut(Judging):
    """Held-out runs of ``seconds`` whose position residual is the replay's own (floors of 1)."""

    def __init__(self, seconds: float) -> None:
        super().__init__([], [], [], Floors(1.0, 1.0, "given", "given"))
        self.seconds = seconds

    @property
    def duration_s(self) -> float:
        return self.seconds

    def residuals(self, replays: Replays) -> Residuals:
        return _residuals(replays.judging[0])


# --- the records: ranking helpers and which candidate a round accepted


def _candidate(name: str, cost: float = 1.0) -> Candidate:
    fit = FitResult(name, {}, {}, cost, 0, "")
    return Candidate(fit, 1, bic(cost, 1, 5.0), NO_REPLAYS, _judged(True))


def _round(
    candidates: list[Candidate],
    accepted: list[str],
    pair: Pair | None = None,
    joint: list[JointCandidate] | None = None,
) -> Round:
    floor = CalibrationFloor(2.0, 1.5, 1.3, {})
    return Round(1, {}, True, 2.0, 1.0, 0.1, floor, [], candidates, accepted, joint or [], [], pair)


def test_bic_charges_each_parameter_the_log_of_the_independent_samples():
    # 5 s of training at one independent sample per 10 ms: n_eff = 500
    assert bic(1.0, 2, 5.0) - bic(1.0, 1, 5.0) == pytest.approx(np.log(500.0))
    assert bic(0.5, 1, 5.0) < bic(1.0, 1, 5.0)


def test_correlation_of_predicted_changes_ignores_sign_and_constants():
    a = np.sin(np.linspace(0.0, 6.0, 50))
    assert correlation(a, -2.0 * a) == pytest.approx(1.0)
    assert correlation(a, np.ones(50)) == 0.0
    assert correlation(a, a[:10]) == 0.0


def test_a_round_names_its_accepted_single_or_pair():
    single = _candidate("stribeck")
    other = _candidate("backlash_change")
    assert _round([other, single], ["stribeck"]).best is single
    assert _round([other, single], []).best is None
    pair = Pair(
        FitResult("backlash_change+stribeck", {}, {}, 0.5, 0, ""),
        3,
        bic(0.5, 3, 5.0),
        NO_REPLAYS,
        _judged(True),
        members=("backlash_change", "stribeck"),
        member_values=((8e-6,), (0.2, 0.3)),
    )
    chosen = _round([other, single], ["backlash_change", "stribeck"], pair)
    assert chosen.best is pair
    assert chosen.best.name == "backlash_change+stribeck"


def test_two_effects_that_each_fail_alone_pass_as_a_pair():
    """Backlash and current lag each leave 3.9 of a gap of 4 (times the noise floor) alone, and
    0.5 together: the pair screen fits the second on top of the first, the pair passes, and each
    member earns its place beside the other."""

    def gap(overrides: dict[str, float]) -> np.ndarray:
        both = {"backlash", "current_time_constant"} <= set(overrides)
        alone = {"backlash", "current_time_constant"} & set(overrides)
        return 2.0 * (0.5 if both else 3.9 if alone else 4.0) * PATTERN

    pool = JointPool(
        gap, {"backlash_change": {"backlash": 8e-6}, "current_lag": {"current_time_constant": 2e-4}}
    )
    held = _HeldOut(10.0).held_out(Replays([gap({})], [gap({})]), pool.basis({}))
    alone = []
    for name, values in pool.fitted.items():
        replays = Replays([gap(values)], [gap(values)])
        fit = FitResult(name, values, values, 1.0, 1, "")
        alone.append(Candidate(fit, 1, 0.0, replays, _judged(False)))
    opened = _round(alone, [])
    (pair,) = _swapping(pool).screen_pairs(opened, {}, held)
    fit = next(t for t in pool.asked if isinstance(t, FitTask))
    assert (fit.hypothesis, fit.base) == ("current_lag", {"backlash": 8e-6})
    assert pair.members == ("backlash_change", "current_lag") and pair.passes
    assert pair.judgement.reduction == pytest.approx(1 - 0.5 / 4.0, rel=0.01)
    assert pair.members_earn_place
    assert [m.effect for m in pair.within] == ["backlash_change", "current_lag"]
    # normalised RMS: the sizes above to 1 % (PATTERN is not a whole number of periods)
    assert all(m.left_with == pytest.approx(0.5, rel=0.01) for m in pair.within)
    assert all(m.left_without == pytest.approx(3.9, rel=0.01) for m in pair.within)
    assert _round(alone, list(pair.members), pair).best is pair


# --- swaps of an accepted effect for a rival of its round

SAMPLES = 2000
PATTERN = np.sin(np.linspace(0.0, 40.0, SAMPLES))  # a structured residual, RMS 0.71

LIBRARY = {
    name: SimpleNamespace(kind="continuous", sets={key: 0}, parameters=(None,), relative_size=None)
    for name, key in (
        ("backlash_change", "backlash"),
        ("stiffness_change", "resonance_frequency"),
        ("inertia_change", "load_inertia"),
        ("current_lag", "current_time_constant"),
    )
}


def _residuals(position: np.ndarray) -> Residuals:
    zeros = np.zeros(len(position))
    return Residuals(np.arange(len(position)) * 0.005, position, zeros, zeros, zeros, zeros, zeros)


@dataclass
class SwapPool:
    """Replays whose residual is ``gap(overrides)``; a rival's fit sets ``fitted[name]`` on
    top of its base, a joint refit ``joint(overrides)``."""

    gap: object
    fitted: dict[str, dict[str, float]]
    joint: object = field(default_factory=lambda: lambda overrides: overrides)
    nominal: dict = field(default_factory=dict)
    calibrated: list = field(default_factory=list)
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
                    sequential[next(iter(LIBRARY[name].sets))] = start[0]
                results.append(FitResult("+", {}, self.joint(sequential), 1.0, 1, ""))
            else:
                assert isinstance(task, SimulateTask) and task.with_training
                residual = self.gap(task.overrides)
                results.append(Replays([residual], [residual]))
        return results

    def joint_fits(self, phase: str, tasks: list, hypotheses: dict, beside=None):
        """Joint refits as the pool runs them: the tasks beside them first, in one batch here."""
        found = self.tasks(phase, [*(beside or []), *tasks])
        return found[len(found) - len(tasks) :], found[: len(found) - len(tasks)]

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        return CalibrationBasis([], np.zeros((2 * SAMPLES, 0)))


def _swapping(pool: SwapPool) -> Selector:
    """The selector of the four-effect library on ``pool`` (held-out runs of 10 s)."""
    return Selector(pool, LIBRARY, _HeldOut(10.0), DiagnosisSettings(), 10.0)


def _rival(name: str, passes: bool, value: float) -> Candidate:
    key = next(iter(LIBRARY[name].sets))
    fit = FitResult(name, {key: value}, {key: value}, 1.0, 1, "")
    return Candidate(fit, 1, 0.0, NO_REPLAYS, _judged(passes))


def _rounds() -> list:
    first = SimpleNamespace(
        candidates=[
            _rival("backlash_change", True, 8e-6),
            _rival("stiffness_change", True, 60.0),
            _rival("inertia_change", False, 5e-4),
        ]
    )
    second = SimpleNamespace(candidates=[_rival("current_lag", True, 2e-4)])
    return [first, second]


def _two_accepted() -> list[Accepted]:
    return [
        Accepted(["backlash_change"], (8e-6,), {"motor_order": 6.0}, 1),
        Accepted(["current_lag"], (2e-4,), {"motor_order": 6.0}, 2),
    ]


SWAP_BASE = {"backlash": 8e-6, "current_time_constant": 2e-4}


def _gap(swapped_left: float):
    """Residual RMS 4 with the backlash, ``swapped_left`` with the stiffness instead."""

    def gap(overrides: dict[str, float]) -> np.ndarray:
        size = swapped_left if "resonance_frequency" in overrides else 4.0
        return 2.0 * size * PATTERN  # normalised RMS: size

    return gap


def test_rivals_are_the_other_passing_hypotheses_of_the_effects_round():
    found = rivals(_rounds(), _two_accepted(), set())
    assert [(j, c.name) for j, c in found] == [(0, "stiffness_change")]
    assert rivals(_rounds(), _two_accepted(), {"stiffness_change"}) == []  # never swapped back in
    unknown = [Accepted(["backlash_change"], (8e-6,), {}, 0)]
    assert rivals(_rounds(), unknown, set()) == []


def test_a_rival_that_leaves_much_less_replaces_its_effect():
    pool = SwapPool(_gap(1.0), {"stiffness_change": {"resonance_frequency": 60.0}})
    accepted, records = _two_accepted(), []
    replays = Replays([_gap(1.0)(SWAP_BASE)], [_gap(1.0)(SWAP_BASE)])
    result = _swapping(pool).swap(_rounds(), accepted, SWAP_BASE, replays, records)
    assert result is not None
    base, after = result
    assert base == {"current_time_constant": 2e-4, "resonance_frequency": 60.0}
    assert np.allclose(after.judging[0], _gap(1.0)(base))
    assert [a.name for a in accepted] == ["stiffness_change", "current_lag"]
    assert accepted[0].round == 1 and accepted[0].context == {"motor_order": 6.0}
    assert [(r.removed, r.candidate.name, r.kept) for r in records] == [
        ("backlash_change", "stiffness_change", True)
    ]
    assert records[0].candidate.passes
    assert records[0].candidate.judgement.gain.evidence_z > 100.0
    fit = next(t for t in pool.asked if isinstance(t, FitTask))
    assert "backlash" not in fit.base and fit.base["current_time_constant"] == 2e-4
    assert fit.start == (60.0,)  # from the rival's fit of its round
    joint = next(t for t in pool.asked if isinstance(t, JointFitTask))
    assert joint.hypotheses == ("stiffness_change", "current_lag")


def test_the_joint_refit_of_the_swapped_model_is_judged_when_it_leaves_less():
    def joint(sequential: dict[str, float]) -> dict[str, float]:
        return {**sequential, "resonance_frequency": 58.0, "refitted": 1.0}

    def gap(overrides: dict[str, float]) -> np.ndarray:
        if "refitted" in overrides:
            return 2.0 * PATTERN  # norm 1
        return (3.0 if "resonance_frequency" in overrides else 4.0) * 2.0 * PATTERN

    pool = SwapPool(gap, {"stiffness_change": {"resonance_frequency": 60.0}}, joint)
    replays = Replays([gap(SWAP_BASE)], [gap(SWAP_BASE)])
    base, _ = _swapping(pool).swap(_rounds(), _two_accepted(), SWAP_BASE, replays, [])
    assert base["refitted"] == 1.0


def test_no_swap_when_the_rival_does_not_fit_better_beyond_the_noise():
    pool = SwapPool(_gap(4.0), {"stiffness_change": {"resonance_frequency": 60.0}})
    accepted, records = _two_accepted(), []
    replays = Replays([_gap(4.0)(SWAP_BASE)], [_gap(4.0)(SWAP_BASE)])
    assert _swapping(pool).swap(_rounds(), accepted, SWAP_BASE, replays, records) is None
    assert [a.name for a in accepted] == ["backlash_change", "current_lag"]
    assert len(records) == 1 and not records[0].kept and not records[0].candidate.passes


def test_nothing_is_fitted_without_rivals():
    pool = SwapPool(_gap(1.0), {})
    records: list[Swap] = []
    replays = Replays([_gap(1.0)(SWAP_BASE)], [_gap(1.0)(SWAP_BASE)])
    accepted = _two_accepted()[1:]
    assert _swapping(pool).swap(_rounds(), accepted, SWAP_BASE, replays, records) is None
    assert pool.asked == [] and records == []


# --- the joint screen: a later round's leaders refitted with the accepted effects free


def _joint_gap(overrides: dict[str, float]) -> np.ndarray:
    """Residual RMS 4 until the backlash is back at 6 um with the stiffness, then 1."""
    both = overrides.get("backlash") == 6e-6 and "resonance_frequency" in overrides
    return 2.0 * (1.0 if both else 4.0) * PATTERN


def _joint_refit(sequential: dict[str, float]) -> dict[str, float]:
    """The joint refit moves the backlash back from 8 to 6 um beside a stiffness change."""
    if "resonance_frequency" in sequential:
        return {**sequential, "backlash": 6e-6}
    return sequential


@dataclass
class JointPool(SwapPool):
    """A :class:`SwapPool` whose joint refits name their values as the replay workers do
    (``effect.parameter``)."""

    def tasks(self, phase: str, tasks: list) -> list:
        if all(isinstance(t, SimulateTask) for t in tasks):  # the candidates' held-out replays
            self.asked.extend(tasks)
            return [Replays(None, [self.gap(t.overrides)]) for t in tasks]
        results = super().tasks(phase, tasks)
        for k, (task, result) in enumerate(zip(tasks, results, strict=True)):
            if isinstance(task, JointFitTask):
                named = {
                    f"{name}.{next(iter(LIBRARY[name].sets))}": result.overrides[
                        next(iter(LIBRARY[name].sets))
                    ]
                    for name in task.hypotheses
                }
                results[k] = FitResult("+".join(task.hypotheses), named, result.overrides, 1, 9, "")
        return results


def _screened(gap, joint) -> tuple[JointPool, list[JointCandidate]]:
    """The joint screen of a round whose one candidate, the stiffness on top of a backlash
    accepted at 8 um, did not pass."""
    pool = JointPool(gap, {}, joint)
    base = {"backlash": 8e-6}
    held = _HeldOut(10.0).held_out(Replays([gap(base)], [gap(base)]), pool.basis(base))
    stiffness = _rival("stiffness_change", False, 60.0)
    accepted = [Accepted(["backlash_change"], (8e-6,), {}, 1)]
    context = {"motor_order": 6.0}
    return pool, _swapping(pool).screen_joint([stiffness], accepted, context, base, held)


def test_the_joint_screen_refits_a_leader_with_the_accepted_effects_and_judges_it():
    pool, joint = _screened(_joint_gap, _joint_refit)
    alone, refit = [t for t in pool.asked if isinstance(t, JointFitTask)]
    assert alone.hypotheses == ("backlash_change",)  # the same refit without a candidate
    assert refit.hypotheses == ("backlash_change", "stiffness_change")
    assert refit.start == ((8e-6,), (60.0,))  # the accepted value and the round's own fit
    assert refit.contexts[1] == {"motor_order": 6.0}
    (candidate,) = joint
    assert candidate.name == "stiffness_change" and candidate.passes
    assert candidate.fit.values == {"resonance_frequency": 60.0}  # its own values only
    assert candidate.fit.overrides == {"backlash": 6e-6, "resonance_frequency": 60.0}
    assert candidate.judgement.reduction == pytest.approx(0.75)
    after = refitted([Accepted(["backlash_change"], (8e-6,), {}, 1)], candidate.refit)
    assert after[0].values == (6e-6,)  # accepted with the others at their refitted values
    assert _round([], ["stiffness_change"], joint=joint).best is candidate


def test_a_gain_the_refit_reaches_without_the_candidate_is_not_the_candidates():
    def gap(overrides: dict[str, float]) -> np.ndarray:  # the backlash at 6 um is all it takes
        return 2.0 * (1.0 if overrides.get("backlash") == 6e-6 else 4.0) * PATTERN

    _, joint = _screened(gap, lambda sequential: {**sequential, "backlash": 6e-6})
    assert len(joint) == 1 and not joint[0].passes
    assert joint[0].judgement.reduction == pytest.approx(0.0)


def test_the_joint_screen_judges_without_a_second_calibration_correction():
    """The refits moved the calibrated parameters themselves: a candidate that cuts the held-out
    RMS by 2 % as it is and by 18 % only after the held-out calibration correction does not
    pass."""
    other = np.sin(np.linspace(0.0, 97.0, SAMPLES))  # a shape calibration error makes

    def gap(overrides: dict[str, float]) -> np.ndarray:
        if "resonance_frequency" in overrides:
            return 2.0 * (3.3 * PATTERN + 2.1 * other)  # RMS 3.9 as it is, 3.3 corrected
        return 2.0 * 4.0 * PATTERN

    judging = _HeldOut(10.0)
    direction = judging.vector(_residuals(2.0 * 2.1 * other))

    @dataclass
    class CalibratedPool(JointPool):
        def basis(self, base: dict[str, float]) -> CalibrationBasis:
            return CalibrationBasis(["motor_inertia"], direction[:, None])

    pool = CalibratedPool(gap, {}, lambda sequential: sequential, calibrated=["motor_inertia"])
    base = {"backlash": 8e-6}
    held = judging.held_out(Replays([gap(base)], [gap(base)]), pool.basis(base))
    stiffness = _rival("stiffness_change", False, 60.0)
    accepted = [Accepted(["backlash_change"], (8e-6,), {}, 1)]
    (candidate,) = _swapping(pool).screen_joint([stiffness], accepted, {}, base, held)
    assert 0.0 < candidate.judgement.reduction < 0.05 and not candidate.passes
    assert candidate.judgement.failed == ["fair share"]
    with_it = judging.vector(_residuals(gap({"resonance_frequency": 60.0})))
    corrected = np.linalg.norm(held.basis.correction(with_it)[1])
    assert corrected < 0.9 * np.linalg.norm(held.left)  # what a second correction would credit


def test_a_joint_refit_that_explains_nothing_more_does_not_pass():
    _, joint = _screened(_joint_gap, lambda sequential: sequential)  # the backlash stays at 8 um
    assert len(joint) == 1 and not joint[0].passes
    single = _candidate("stiffness_change")
    assert _round([single], ["stiffness_change"], joint=joint).best is single


# --- a round's passing candidates judged again with the calibration corrections replayed

SHAPE = np.sin(np.linspace(0.0, 97.0, SAMPLES))  # a shape a calibrated parameter's move makes


def _correcting(explained_by_calibration: bool):
    """Held-out residuals of a world where calibration error either explains most of the
    pattern once its correction is replayed (what the linear correction cannot see) or not."""

    def gap(overrides: dict[str, float]) -> np.ndarray:
        size = 3.0 if "resonance_frequency" in overrides else 4.0
        if "motor_inertia" in overrides:  # a replayed correction
            return 2.0 * (1.5 if explained_by_calibration else size) * PATTERN
        return 2.0 * (size * PATTERN + SHAPE)

    return gap


@dataclass
class CorrectingPool(JointPool):
    """A pool with one calibrated parameter, the motor inertia, moved by 3 % a tolerance."""

    calibrated: list = field(default_factory=lambda: ["motor_inertia"])
    bases: list = field(default_factory=list)

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        self.bases.append(base)
        return CalibrationBasis(
            ["motor_inertia"], _HeldOut(10.0).vector(_residuals(2 * SHAPE))[:, None]
        )

    def corrected(self, base: dict[str, float], coefficients: dict[str, float]) -> dict[str, float]:
        return {**base, "motor_inertia": 1.0 + 0.03 * coefficients["motor_inertia"]}


def _replayed_round(explained_by_calibration: bool) -> tuple[CorrectingPool, list[Candidate]]:
    """A round of two candidates on top of the nominal twin, a stiffness change that cuts the
    pattern from 4 to 3 and a backlash change that changes nothing, judged with the corrections
    replayed."""
    gap = _correcting(explained_by_calibration)
    pool = CorrectingPool(gap, {})
    judging = _HeldOut(10.0)
    held = judging.held_out(Replays(None, [gap({})]), pool.basis({}))
    acceptance = judging.acceptance(DiagnosisSettings(), 2, 12)
    candidates = []
    for name, overrides in (
        ("stiffness_change", {"resonance_frequency": 60.0}),
        ("backlash_change", {"backlash": 8e-6}),
    ):
        replays = Replays(None, [gap(overrides)])
        judgement = judge(replays, held, judging, acceptance, 1.1, True)
        fit = FitResult(name, overrides, overrides, 1.0, 1, "")
        candidates.append(Candidate(fit, 1, 0.0, replays, judgement))
    return pool, _swapping(pool).replay_corrections(candidates, {}, held)


def test_a_gain_that_a_replayed_calibration_correction_explains_does_not_pass():
    pool, (stiffness, backlash) = _replayed_round(explained_by_calibration=True)
    assert stiffness.judgement.gain.passes  # against the linear corrections
    assert stiffness.judgement.replayed is not None
    assert stiffness.judgement.replayed.excess_share == pytest.approx(0.0, abs=1e-9)
    assert stiffness.judgement.failed == ["replayed correction"] and not stiffness.passes
    assert backlash.judgement.replayed is None  # it failed already: not replayed
    # the passing candidate's own calibration directions, beside the model's of the round
    assert pool.bases == [{}, {"resonance_frequency": 60.0}]
    # the model as it is and the one passing candidate, each with its own linear correction
    assert [t.overrides for t in pool.asked] == [
        {"motor_inertia": pytest.approx(1.03, rel=1e-3)},
        {"resonance_frequency": 60.0, "motor_inertia": pytest.approx(1.03, rel=1e-3)},
    ]


def test_a_gain_that_holds_with_the_corrections_replayed_passes():
    _, (stiffness, backlash) = _replayed_round(explained_by_calibration=False)
    assert stiffness.passes and stiffness.judgement.replayed is not None
    assert stiffness.judgement.replayed.excess_share == pytest.approx((16 - 9) / 15, rel=1e-3)
    assert not backlash.passes


def test_without_calibrated_parameters_nothing_is_replayed_again():
    pool = CorrectingPool(_correcting(True), {}, calibrated=[])
    candidate = _candidate("stiffness_change")
    held = _HeldOut(10.0).held_out(Replays(None, [PATTERN]), pool.basis({}))
    assert _swapping(pool).replay_corrections([candidate], {}, held) == [candidate]
    assert pool.asked == []


# --- cold refits of the accepted effects on top of the others

CARD = {h.name: h for h in plant_model("drive2mass").hypotheses}
REFIT_LIBRARY = {
    "stribeck": SimpleNamespace(
        kind="continuous",
        relative_size=None,
        sets={"stribeck_friction": 0, "stribeck_speed": 0},
        parameters=CARD["stribeck"].parameters,  # a level and a shape (log) parameter
    ),
    "inertia_change": SimpleNamespace(
        kind="continuous",
        relative_size=None,
        sets={"motor_inertia": 0},
        parameters=CARD["inertia_change"].parameters,
    ),
    "dead_time": SimpleNamespace(
        kind="scan",
        relative_size=None,
        sets={"dead_time_steps": 0},
        parameters=CARD["dead_time"].parameters,
    ),
}


@dataclass
class RefitPool:
    """Refits return ``refits[(name, profile)]`` or else ``refits[name]`` on top of their base;
    ``left`` is ``lefts[overrides]`` (a number: that many times a unit vector of 100 samples; or
    the vector itself)."""

    refits: dict[str | tuple[str, bool], dict[str, float]]
    lefts: dict[tuple, float | np.ndarray]
    asked: list = field(default_factory=list)

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


def _refitting(pool: RefitPool, library: dict | None = None) -> Selector:
    """The selector on ``pool``; the held-out data last 1 s (100 independent samples per
    signal)."""
    return Selector(pool, library or REFIT_LIBRARY, _HeldOut(1.0), DiagnosisSettings(), 1.0)


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
    pool = RefitPool({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    accepted = _accepted()
    refitted = _refitting(pool).refresh(accepted, BASE, Replays([BASE], [BASE]))
    assert refitted is not None
    base, replays, record = refitted
    assert base == {**BASE, **stribeck}
    assert replays.judging == [base]
    assert accepted[0].values == (0.16, 0.58)
    assert accepted[1].values == (0.15,)  # the other refit left more: unchanged
    fits = [t for t in pool.asked if isinstance(t, FitTask)]
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
    assert record.gain.excess_share == 1.0
    assert abs(record.gain.evidence_z - 13.44 / (2 * 2.8 / np.sqrt(200))) < 1e-9
    assert abs(record.gain.critical_z - 2.713) < 1e-3  # level 0.01 shared by the three refits
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
    pool = RefitPool(refits, lefts)
    accepted = _accepted()
    base, _, record = _refitting(pool).refresh(accepted, BASE, Replays([BASE], [BASE]))
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
    pool = RefitPool({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    refitted = _refitting(pool).refresh(_accepted(), BASE, Replays([BASE], [BASE]))
    assert refitted is not None
    base, _, record = refitted
    assert base == {**BASE, **stribeck}
    assert record.left_after < record.left_before
    assert record.gain.evidence_z < record.gain.critical_z
    assert not record.significant


def test_a_refit_needs_its_fair_share_of_the_excess_to_be_significant():
    """A gain far beyond the noise that removes under 1/12 of the excess energy is no gain."""
    before = np.zeros(10_000)
    before[0] = 10.0  # energy 100, excess 99
    after = before.copy()
    after[0] = np.sqrt(100.0 - 5.0)  # removes 5 of the 99: z large, share 0.05 < 1/12
    stribeck = {"stribeck_friction": 0.11, "stribeck_speed": 0.86}
    library = {**REFIT_LIBRARY, **{f"other_{k}": REFIT_LIBRARY["dead_time"] for k in range(9)}}
    pool = RefitPool(
        {"stribeck": stribeck, "inertia_change": {"motor_inertia": 3.4e-4}},
        {
            _key(BASE): before,
            _key({**BASE, **stribeck}): after,
            _key({**BASE, "motor_inertia": 3.4e-4}): 11.0,
        },
    )
    _, _, record = _refitting(pool, library).refresh(_accepted(), BASE, Replays([BASE], [BASE]))
    assert record.gain.evidence_z > record.gain.critical_z
    assert abs(record.gain.excess_share - 5.0 / 99.0) < 1e-12
    assert record.gain.fair_share == 1.0 / 12.0
    assert not record.significant


def test_the_model_stays_as_it_is_when_no_refit_leaves_less():
    stribeck = {"stribeck_friction": 0.05, "stribeck_speed": 1.9}
    inertia = {"motor_inertia": 3.4e-4}
    lefts = {_key(BASE): 1.0, _key({**BASE, **stribeck}): 1.2, _key({**BASE, **inertia}): 1.0}
    pool = RefitPool({"stribeck": stribeck, "inertia_change": inertia}, lefts)
    accepted = _accepted()
    assert _refitting(pool).refresh(accepted, BASE, Replays([BASE], [BASE])) is None
    assert [a.values for a in accepted] == [a.values for a in _accepted()]


def test_a_single_effect_is_not_refitted():
    pool = RefitPool({}, {})
    assert _refitting(pool).refresh(_accepted()[:1], BASE, Replays([BASE], [BASE])) is None
    assert pool.asked == []


@dataclass
class ScreenPool:
    """Fits whose training cost is ``local[name]`` from the start values, ``searched[name]``
    from the global search and ``profiled[name]`` from the profile over a shape parameter."""

    local: dict[str, float]
    searched: dict[str, float]
    profiled: dict[str, float] = field(default_factory=dict)
    batches: list = field(default_factory=list)

    def tasks(self, phase: str, tasks: list) -> list:
        assert phase in ("first_round_fits", "later_round_fits")
        self.batches.append(tasks)
        costs = [
            self.profiled if t.profile else self.searched if t.search else self.local for t in tasks
        ]
        return [
            FitResult(
                t.hypothesis,
                {},
                dict(t.base),
                cost[t.hypothesis],
                1,
                "",
                search_replays=int(t.search),
            )
            for t, cost in zip(tasks, costs, strict=True)
        ]


SCREENED = ["stribeck", "coulomb_change", "pitch_error", "dead_time", "inertia_change"]


def _screen(pool: ScreenPool) -> list[FitResult]:
    drive2mass = {h.name: h for h in plant_model("drive2mass").hypotheses}
    library = {name: drive2mass[name] for name in SCREENED}
    settings = DiagnosisSettings(searched_candidates=2)
    selector = Selector(pool, library, _HeldOut(10.0), settings, 10.0)
    return selector._screened(SCREENED, {"motor_inertia": 3.3e-4}, {})


def test_the_first_round_searches_the_leaders_of_its_screen_fits_only():
    """Every hypothesis is fitted from its start values, but for a level and a shape (the
    Stribeck curve), whose rough cost no local fit screens: it is fitted from its profile. The
    two leading ones by training BIC of those with a search are fitted again from it. A scanned
    hypothesis and one of three parameters have no search: however well they fit, they are not
    searched again."""
    local = {"coulomb_change": 3.0, "pitch_error": 0.5, "dead_time": 0.4, "inertia_change": 4.0}
    pool = ScreenPool(local, {"coulomb_change": 2.9, "inertia_change": 3.5}, {"stribeck": 5.0})
    fits = _screen(pool)
    first, again = pool.batches
    assert [(t.hypothesis, t.search, t.profile) for t in first] == [
        ("stribeck", True, True),
        *((n, False, False) for n in SCREENED[1:]),
    ]
    assert [(t.hypothesis, t.search, t.start) for t in again] == [
        ("coulomb_change", True, None),  # BIC: 3.0 with one parameter leads 4.0 with one
        ("inertia_change", True, None),
    ]
    # stribeck (two parameters, 5.0) trails: its profile fit stays its fit
    assert [f.train_cost for f in fits] == [5.0, 2.9, 0.5, 0.4, 3.5]
    assert [f.replays for f in fits] == [1, 2, 1, 1, 2]  # a leader's: its local fit's and its own


def test_a_leaders_search_replaces_its_local_fit_even_where_that_fit_the_training_better():
    """A local fit is no search: the leader's global search is its fit, as it always was."""
    local = {"coulomb_change": 2.0, "pitch_error": 0.5, "dead_time": 0.4, "inertia_change": 4.0}
    pool = ScreenPool(local, {"coulomb_change": 2.5, "inertia_change": 3.5}, {"stribeck": 5.0})
    fits = _screen(pool)
    assert [f.train_cost for f in fits] == [5.0, 2.5, 0.5, 0.4, 3.5]


@pytest.mark.parametrize(("searched", "kept"), [(1.2, 1.0), (0.8, 0.8)])
def test_a_leading_profile_fit_is_searched_too_and_the_better_kept(searched, kept):
    """Both are searches that stop in different valleys of a rough cost: the one that fits the
    training data better is the hypothesis' fit, with the replays of both."""
    local = {"coulomb_change": 3.0, "pitch_error": 0.5, "dead_time": 0.4, "inertia_change": 4.0}
    pool = ScreenPool(local, {"stribeck": searched, "coulomb_change": 2.9}, {"stribeck": 1.0})
    fits = _screen(pool)
    assert [t.hypothesis for t in pool.batches[1]] == ["stribeck", "coulomb_change"]
    assert fits[0].train_cost == kept
    assert (fits[0].replays, fits[0].search_replays) == (2, 2)


def test_a_later_round_fits_a_level_and_shape_from_its_start_and_its_profile():
    """A later round starts each fit from the round before's; a level and a shape is also fitted
    from its profile (the accepted effects can move its valley), the better of the two kept."""
    drive2mass = {h.name: h for h in plant_model("drive2mass").hypotheses}
    library = {name: drive2mass[name] for name in ("stribeck", "coulomb_change")}
    starts = {"stribeck": (0.1, 0.5), "coulomb_change": (0.02,)}
    for warm, kept in ((2.0, 1.5), (1.0, 1.0)):
        pool = ScreenPool({}, {"stribeck": warm, "coulomb_change": 1.0}, {"stribeck": 1.5})
        selector = Selector(pool, library, _HeldOut(10.0), DiagnosisSettings(), 10.0)
        fits = selector._continued(list(starts), {}, {}, starts)
        (asked,) = pool.batches
        assert [(t.hypothesis, t.start, t.profile) for t in asked] == [
            ("stribeck", (0.1, 0.5), False),
            ("coulomb_change", (0.02,), False),
            ("stribeck", None, True),
        ]
        assert [f.train_cost for f in fits] == [kept, 1.0]
        assert [f.replays for f in fits] == [2, 1]


def test_a_later_round_starts_only_from_fits_that_searched():
    """A local fit the screen left alone found no valley: the next round searches that
    hypothesis afresh; a searched fit, or one of a hypothesis without a search, is a start."""
    drive2mass = {h.name: h for h in plant_model("drive2mass").hypotheses}
    selector = Selector(ScreenPool({}, {}), drive2mass, _HeldOut(10.0), DiagnosisSettings(), 10.0)

    def fitted(name: str, search_replays: int) -> Candidate:
        fit = FitResult(name, {}, {}, 1.0, 1, "", search_replays=search_replays)
        return Candidate(fit, 1, 0.0, NO_REPLAYS, _judged(False))

    assert not selector._found(fitted("coulomb_change", 0))  # the screen's local fit
    assert selector._found(fitted("coulomb_change", 32))  # its global search
    assert selector._found(fitted("pitch_error", 0))  # three parameters: never searched
