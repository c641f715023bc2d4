"""Motion envelopes of known references, and what of a held-out one lies beyond the tuning's."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.motion_envelope import MotionEnvelope, envelope_of, outside
from twin_cosim.reference import ReferenceGrid

PERIOD = 250e-6  # s


def grid(pieces: list[tuple[float, float]]) -> ReferenceGrid:
    """A reference from (duration s, acceleration m/s^2) pieces, integrated exactly."""
    acceleration = np.concatenate([np.full(round(d / PERIOD), a) for d, a in pieces])
    velocity = np.concatenate([[0.0], np.cumsum(acceleration[:-1]) * PERIOD])
    position = np.concatenate([[0.0], np.cumsum(velocity[:-1]) * PERIOD])
    return ReferenceGrid(PERIOD, position, velocity, acceleration)


def test_known_regimes_are_measured():
    reference = grid(
        [
            (0.2, 0.0),  # dwell
            (0.1, 0.1),  # start from the dwell at 0.1 m/s^2 to 10 mm/s
            (0.2, 0.0),
            (0.2, -0.1),  # 10 mm/s to -10 mm/s: a reversal while moving at 0.1 m/s^2
            (0.1, 0.0),
            (0.04, 0.25),  # -10 mm/s to 0
            (0.2, 0.0),  # dwell
            (0.04, -0.5),  # start from the dwell at 0.5 m/s^2 to -20 mm/s
            (0.04, 0.5),
        ]
    )
    found = envelope_of(reference)
    assert found.speed == pytest.approx(0.02, rel=1e-9)
    assert found.acceleration == pytest.approx(0.5)
    assert found.reversal_acceleration == pytest.approx(0.1)
    assert found.start_acceleration == pytest.approx(0.5)


def test_a_stop_shorter_than_a_dwell_is_a_reversal_while_moving():
    # 10 mm/s to -10 mm/s at 0.3 m/s^2 with 10 ms at standstill in between (< 50 ms).
    reference = grid([(0.1, 0.1), (0.2, 0.0), (1 / 30, -0.3), (0.01, 0.0), (1 / 30, -0.3)])
    found = envelope_of(reference)
    assert found.reversal_acceleration == pytest.approx(0.3)
    assert found.start_acceleration == 0.0  # it started at t = 0, after no dwell


def test_outside_names_each_figure_beyond_the_margin():
    tuned = [MotionEnvelope(0.03, 0.2, 0.02, 0.02), MotionEnvelope(0.04, 0.5, 0.1, 0.2)]
    assert outside(MotionEnvelope(0.045, 0.55, 0.11, 0.2), tuned) == []  # within 20 %
    lines = outside(MotionEnvelope(0.12, 0.5, 0.2, 0.6), tuned)
    assert lines == [
        "speed 120 mm/s (tuned: up to 40)",
        "reversal while moving at 0.2 m/s^2 (tuned: up to 0.1)",
        "start from a dwell at 0.6 m/s^2 (tuned: up to 0.2)",
    ]
