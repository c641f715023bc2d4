"""Reference generation against kinematics, and its error messages.

Motion envelopes of known references, and what of a held-out one lies beyond the tuning's.
"""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.reference import (
    Dwell,
    MotionEnvelope,
    Move,
    Oscillation,
    Ramp,
    ReferenceError,
    ReferenceGrid,
    envelope_of,
    interpolate,
    outside,
    read_reference_csv,
    sample_segments,
)


def test_trapezoidal_move_kinematics():
    samples = sample_segments([Move(0.01, 0.02, 0.5), Dwell(0.1)], 0.004)
    grid = interpolate(samples, 0.004, 250e-6)
    duration = 0.01 / 0.02 + 0.02 / 0.5  # distance/v + v/a
    assert grid.position[-1] == pytest.approx(0.01, abs=1e-12)
    assert grid.duration == pytest.approx(duration + 0.1, abs=0.004)
    assert np.abs(grid.velocity).max() == pytest.approx(0.02, rel=0.01)
    assert np.abs(grid.acceleration).max() == pytest.approx(0.5, rel=0.15)


def test_triangular_move_when_short():
    samples = sample_segments([Move(1e-4, 0.1, 1.0)], 0.004)
    assert samples[-1] == pytest.approx(1e-4)
    assert len(samples) - 1 == pytest.approx(2 * np.sqrt(1e-4 / 1.0) / 0.004, abs=1)


def test_ramps_chain_velocity_levels():
    samples = sample_segments(
        [Ramp(0.01, 0.1, 1.0), Ramp(0.02, 0.1, 1.0), Ramp(0.0, 0.1, 0.2)], 0.004
    )
    grid = interpolate(samples, 0.004, 250e-6)
    t = grid.time
    assert grid.velocity[(t > 0.5) & (t < 0.9)] == pytest.approx(0.01, rel=1e-6)
    assert grid.velocity[(t > 1.5) & (t < 1.7)] == pytest.approx(0.02, rel=1e-6)
    # position = area under the speed profile
    assert samples[-1] == pytest.approx(
        0.01 * 1.0 - 0.5 * 0.01 * 0.1 + 0.02 * 1.0 - 0.5 * 0.01 * 0.1 + 0.5 * 0.02 * 0.2, rel=1e-9
    )


def test_oscillation_returns_home():
    samples = sample_segments([Oscillation(0.004, 2.0, 3)], 0.004)
    assert samples[-1] == pytest.approx(0.0, abs=1e-12)
    assert samples.max() == pytest.approx(0.004, rel=1e-3)


def test_interpolation_passes_through_the_samples():
    samples = sample_segments([Dwell(0.05), Oscillation(0.01, 1.0, 1), Dwell(0.05)], 0.004)
    grid = interpolate(samples, 0.004, 250e-6)
    np.testing.assert_allclose(grid.position[::16], samples, atol=1e-15)


@pytest.mark.parametrize(
    ("segments", "message"),
    [
        ([], "at least one segment"),
        ([Ramp(0.01, 0.1, 1.0)], "ends moving"),
        ([Ramp(0.01, 0.1, 0.01)], "longer than the segment"),
        ([Ramp(0.01, 0.1, 1.0), Dwell(0.1)], "only a ramp may follow"),
    ],
)
def test_segment_errors(segments, message):
    with pytest.raises(ReferenceError, match=message):
        sample_segments(segments, 0.004)


def test_csv_reference(tmp_path):
    path = tmp_path / "ref.csv"
    path.write_text("t,x_ref\n" + "".join(f"{k * 0.004},{k * 1e-5}\n" for k in range(10)))
    np.testing.assert_allclose(read_reference_csv(path, 0.004), np.arange(10) * 1e-5)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("t,pos\n0,0\n", "missing column 'x_ref'"),
        ("t,x_ref\n0,0\n0.004,nan\n0.008,0\n0.012,0\n", "non-finite"),
        ("t,x_ref\n0,0\n0.005,0\n0.008,0\n0.012,0\n", "step by sample_period"),
    ],
)
def test_csv_reference_errors(tmp_path, text, message):
    path = tmp_path / "ref.csv"
    path.write_text(text)
    with pytest.raises(ReferenceError, match=message) as info:
        read_reference_csv(path, 0.004)
    assert "ref.csv" in str(info.value)


def test_an_interpolated_reference_is_read_back_from_the_cache(tmp_path, monkeypatch):
    """The second interpolation of the same samples reads the stored grid: the same bits as
    SciPy's spline; other samples or periods are interpolated anew."""
    from scipy.interpolate import CubicSpline

    monkeypatch.setenv("TWIN_COSIM_CACHE", str(tmp_path))
    samples = sample_segments([Move(0.01, 0.02, 0.5), Dwell(0.1)], 0.004)
    first = interpolate(samples, 0.004, 250e-6)
    (stored,) = (tmp_path / "references").iterdir()
    again = interpolate(samples, 0.004, 250e-6)
    spline = CubicSpline(np.arange(len(samples)) * 0.004, samples, bc_type="clamped")
    for derivative, name in enumerate(("position", "velocity", "acceleration")):
        exact = spline(first.time, derivative)
        assert np.array_equal(getattr(first, name), exact)
        assert np.array_equal(getattr(again, name), exact)
    interpolate(samples, 0.004, 500e-6)
    interpolate(samples * 2, 0.004, 250e-6)
    assert len(list((tmp_path / "references").iterdir())) == 3
    assert stored.exists()


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
