"""The acceptance rule: one value asked by every step, and the immutable judgement of a fitted
candidate on held-out runs whose residual is the replay's own (floors of 1)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.evidence import CalibrationBasis, critical_z
from twin_cosim.gap.floors.noise import Floors
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.acceptance import Acceptance, Judging, judge, size_above_tolerance
from twin_cosim.gap.which.replay import Replays
from twin_cosim.plant_model import plant_model

SAMPLES = 1000  # 5 s at 5 ms
WAVE = np.sin(np.linspace(0.0, 40.0, SAMPLES))
PATTERN = WAVE / np.sqrt(np.mean(WAVE**2))  # RMS 1


class _Replayed(Judging):
    """Held-out runs of 5 s whose residual is (position, current) of the replay itself."""

    def __init__(self) -> None:
        super().__init__([], [], [], Floors(1.0, 1.0, "given", "given"))

    @property
    def duration_s(self) -> float:
        return 5.0

    def residuals(self, replays: Replays) -> Residuals:
        position, current = replays.judging
        zeros = np.zeros(SAMPLES)
        return Residuals(np.arange(SAMPLES) * 0.005, position, current, zeros, zeros, zeros, zeros)


def _replays(position: float, current: float) -> Replays:
    """A model whose held-out residuals are the pattern at these RMS values (the normalised
    RMS of both: sqrt((position^2 + current^2) / 2))."""
    return Replays(None, [position * PATTERN, current * PATTERN])


NO_CALIBRATION = CalibrationBasis([], np.zeros((2 * SAMPLES, 0)))


def test_the_rule_asks_the_bonferroni_quantile_and_a_fair_share_per_hypothesis():
    rule = Acceptance(0.01, 12, 12, 5.0)
    before = np.full(100, 0.3)  # energy 9, excess 8
    after = np.full(100, 0.1)  # energy 1: all of the excess
    gain = rule.gain(before, after)
    assert gain.critical_z == critical_z(0.01, 12)
    assert gain.fair_share == 1.0 / 12.0 and rule.gain(before, after, shares=2).fair_share == 2 / 12
    assert gain.excess_share == pytest.approx(1.0) and gain.passes and gain.strength >= 1.0
    small = rule.gain(before, before * 0.999)  # a change within the noise
    assert not small.passes and small.strength < 1.0
    assert Acceptance(0.01, 1000, 12, 5.0).gain(before, after).critical_z > gain.critical_z


def test_a_change_that_halves_the_gap_passes_and_its_judgement_is_a_record():
    judging = _Replayed()
    held = judging.held_out(_replays(4.0, 4.0), NO_CALIBRATION)
    rule = judging.acceptance(DiagnosisSettings(), 12, 12)
    judged = judge(_replays(2.0, 2.0), held, judging, rule, 1.1, size_above=True)
    assert judged.reduction == pytest.approx(0.5) and judged.consistent and judged.passes
    assert judged.holdout_rms == pytest.approx(2.0)
    assert judged.explained == pytest.approx(np.sqrt(16.0 - 4.0))
    with pytest.raises(dataclasses.FrozenInstanceError):
        judged.reduction = 1.0  # type: ignore[misc]


def test_a_gain_judged_again_keeps_its_rule_and_a_failed_one_names_its_test():
    rule = Acceptance(0.01, 12, 12, 5.0)
    before, after = np.full(100, 0.3), np.full(100, 0.1)
    gain = rule.gain(before, after, shares=2)
    again = gain.of(before, before * 0.999, 5.0)  # with the corrections replayed: no gain
    assert (again.critical_z, again.fair_share) == (gain.critical_z, gain.fair_share)
    assert again.evidence_z == rule.gain(before, before * 0.999).evidence_z
    assert not again.passes
    judging = _Replayed()
    held = judging.held_out(_replays(4.0, 4.0), NO_CALIBRATION)
    judged = judge(
        _replays(2.0, 2.0),
        held,
        judging,
        judging.acceptance(DiagnosisSettings(), 12, 12),
        1.1,
        True,
    )
    assert dataclasses.replace(judged, replayed=gain).passes
    assert dataclasses.replace(judged, replayed=again).failed == ["replayed correction"]


def test_a_change_that_trades_one_signal_for_the_other_or_is_too_small_fails():
    judging = _Replayed()
    held = judging.held_out(_replays(4.0, 1.0), NO_CALIBRATION)
    rule = judging.acceptance(DiagnosisSettings(), 12, 12)
    traded = judge(_replays(0.5, 3.0), held, judging, rule, 1.1, size_above=True)
    assert traded.reduction > 0.0 and traded.gain.passes
    assert not traded.consistent and not traded.passes  # the current got three times worse
    within_tolerance = judge(_replays(2.0, 1.0), held, judging, rule, 1.1, size_above=False)
    assert within_tolerance.gain.passes and not within_tolerance.passes


def test_a_change_of_a_calibrated_parameter_must_exceed_the_tolerance():
    library = {h.name: h for h in plant_model("drive2mass").hypotheses}
    nominal = {"motor_inertia": 2.9e-4, "load_inertia": 4.2e-4, "coulomb_friction": 0.625}
    inertia = library["inertia_change"]
    assert not size_above_tolerance(inertia, (0.02,), nominal, 0.03)
    assert size_above_tolerance(inertia, (0.2,), nominal, 0.03)
    # a Stribeck rise within the Coulomb level's tolerance (0.019 N.m) could be calibration error
    assert not size_above_tolerance(library["stribeck"], (0.008, 0.5), nominal, 0.03)
    assert size_above_tolerance(library["stribeck"], (0.08, 0.5), nominal, 0.03)
    assert size_above_tolerance(library["torque_ripple"], (0.001, 0.0), nominal, 0.03)  # no size
