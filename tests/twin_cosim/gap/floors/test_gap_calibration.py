"""The calibration floor: the best correction within the tolerance, and what it leaves."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.floors.calibration import CalibrationBasis, floor_of


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
