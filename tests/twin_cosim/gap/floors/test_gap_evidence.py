"""The evidence of a held-out residual against its floors: the calibration correction explains
what lies within the tolerance, and the tests of a gap and of an improvement against their
statistics (noise alone, a real change, a wrong hypothesis)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.gap.floors.evidence import (
    EFFECTIVE_SAMPLE_SPACING_S,
    CalibrationBasis,
    critical_z,
    excess_share,
    fair_share,
    floor_of,
    gap_threshold,
    improvement_z,
)


def basis() -> CalibrationBasis:
    rng = np.random.default_rng(0)
    return CalibrationBasis(["inertia", "friction"], rng.normal(0, 0.1, (500, 2)))


def test_a_residual_within_the_tolerance_is_explained():
    b = basis()
    residual = b.directions @ np.array([0.6, -0.3])
    floor = floor_of(b, residual)
    assert floor.left == pytest.approx(0.0, abs=1e-9)
    assert floor.coefficients["inertia"] == pytest.approx(0.6)
    assert floor.explained == pytest.approx(np.linalg.norm(residual))


def test_a_residual_beyond_the_tolerance_is_not():
    b = basis()
    column = b.directions[:, 0]
    floor = floor_of(b, 3.0 * column)  # three tolerances: only one can be explained
    assert floor.coefficients["inertia"] == pytest.approx(1.0, abs=1e-6)
    assert floor.left == pytest.approx(2.0 * np.linalg.norm(column), rel=0.05)


def test_an_orthogonal_effect_is_left_whole():
    b = basis()
    effect = np.zeros(500)
    effect[100:110] = 1.0
    effect -= b.directions @ np.linalg.lstsq(b.directions, effect, rcond=None)[0]
    floor = floor_of(b, effect)
    assert floor.left == pytest.approx(np.linalg.norm(effect), rel=1e-6)


def test_the_reduced_problem_gives_the_full_problem_s_correction():
    """Solved on the QR factors, the bounded fit is the one on every sample, bounds active or
    not, a direction without effect (a zero column) included."""
    from scipy.optimize import lsq_linear

    rng = np.random.default_rng(3)
    directions = rng.normal(0, 0.1, (2000, 4))
    directions[:, 3] = 0.0
    b = CalibrationBasis(["a", "b", "c", "d"], directions)
    for true in ([0.2, -0.5, 0.1, 0.0], [2.5, -0.3, -4.0, 0.0]):
        residual = directions @ np.array(true) + rng.normal(0, 0.05, 2000)
        coefficients, left = b.correction(residual)
        full = lsq_linear(directions, residual, bounds=(-1.0, 1.0))
        assert np.all(np.abs(coefficients) <= 1.0 + 1e-12)
        assert np.linalg.norm(left) == pytest.approx(np.linalg.norm(full.fun), rel=1e-9)
        assert coefficients[:3] == pytest.approx(full.x[:3], abs=1e-6)


DURATION_S = 6.0  # s of held-out data
DT = EFFECTIVE_SAMPLE_SPACING_S  # one independent sample per spacing: white noise is exact here
N = int(DURATION_S / DT)


def noise(rng: np.random.Generator) -> np.ndarray:
    """A normalised residual of white noise at the floors (squared norm about 1)."""
    return rng.normal(0.0, 1.0, 2 * N) / math.sqrt(2 * N)


def test_critical_z_is_the_bonferroni_normal_quantile():
    assert critical_z(0.05) == pytest.approx(1.6449, abs=1e-4)
    assert critical_z(0.01, 12) == pytest.approx(critical_z(0.01 / 12), abs=1e-12)
    assert critical_z(0.01, 12) > critical_z(0.01, 1)


def test_noise_alone_passes_the_gap_test_at_its_level():
    rng = np.random.default_rng(0)
    level = 0.05
    threshold = gap_threshold(DURATION_S, level)
    exceed = np.mean([np.linalg.norm(noise(rng)) >= threshold for _ in range(2000)])
    assert exceed <= level  # the floors' uncertainty allowance makes it conservative
    assert np.linalg.norm(noise(rng) * 1.5) >= threshold  # noise 1.5 x the floor is a gap


def test_a_hypothesis_that_explains_nothing_has_no_evidence():
    """Under noise, a change unrelated to the residual is rejected at about the level."""
    rng = np.random.default_rng(1)
    critical = critical_z(0.01, 12)
    z = []
    for _ in range(2000):
        before = noise(rng)
        change = 0.05 * noise(rng)  # what a wrong hypothesis predicts
        z.append(improvement_z(before, before - change, DURATION_S))
    assert np.mean(np.array(z) >= critical) <= 0.01 / 12 + 0.002
    assert np.median(z) < 0.0  # fitting the noise's opposite makes the fit worse


def test_a_real_effect_has_evidence_and_its_share():
    rng = np.random.default_rng(2)
    n = noise(rng)
    effect = np.sin(np.linspace(0.0, 40.0, 2 * N)) * 0.8  # structured, 0.8 x the noise RMS x sqrt2
    before, after = n + effect, n
    assert improvement_z(before, after, DURATION_S) > 20.0 * critical_z(0.01, 12)
    share = excess_share(before, after)
    assert share == pytest.approx(1.0, abs=0.15)  # it takes all the energy above the noise
    assert share >= fair_share(12)


def test_a_wrong_hypothesis_fitting_a_little_of_another_effect_lacks_its_share():
    """Structure left by another effect: far beyond the noise, but a small share of it."""
    rng = np.random.default_rng(3)
    n = noise(rng)
    other = np.sign(np.sin(np.linspace(0.0, 25.0, 2 * N))) * 5.0  # another effect's residual
    wrong = 0.03 * other  # a hypothesis that follows 3 % of it (6 % of its energy)
    before, after = n + other, n + other - wrong
    assert improvement_z(before, after, DURATION_S) > critical_z(0.01, 12)  # beyond the noise
    assert excess_share(before, after) < fair_share(12)  # but not its share


def test_no_excess_no_share():
    rng = np.random.default_rng(4)
    before = 0.5 * noise(rng)
    assert excess_share(before, 0.9 * before) == 0.0
