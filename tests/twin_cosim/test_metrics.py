"""Metrics of records whose indices are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.metrics import compute_metrics, indices, sample_period
from twin_cosim.run_record import RunRecord


def record(error: np.ndarray, current: np.ndarray, dt: float = 250e-6) -> RunRecord:
    columns = {"t": np.arange(len(error)) * dt, "error": error, "current": current}
    return RunRecord.from_columns(columns, {"t": "s", "error": "m", "current": "A"})


def test_constant_error_and_current():
    n = 40001  # 10 s at 250 us
    m = compute_metrics(record(np.full(n, -2e-6), np.full(n, 0.5)))
    assert m.E_pk_um == pytest.approx(2.0)
    assert m.rms_um == pytest.approx(2.0)
    assert m.ITAE == pytest.approx(2.0 * 10.0**2 / 2, rel=1e-3)  # int t |e| dt = e T^2 / 2
    assert m.IAU == pytest.approx(0.5 * 10.0, rel=1e-3)
    assert m.max_current_A == 0.5


def test_peak_and_window():
    error = np.zeros(4001)
    error[1000] = 5e-6
    error[3000] = -9e-6
    m = compute_metrics(record(error, np.zeros(4001)), window=(0.0, 0.5))
    assert (m.E_pk_um, m.t_E_pk) == (pytest.approx(5.0), pytest.approx(0.25))
    assert compute_metrics(record(error, np.zeros(4001))).E_pk_um == pytest.approx(9.0)


def test_bad_records_are_refused():
    with pytest.raises(ValueError, match="fewer than two samples"):
        compute_metrics(record(np.zeros(10), np.zeros(10)), window=(5.0, 6.0))
    with pytest.raises(ValueError, match="non-finite"):
        compute_metrics(record(np.array([0.0, np.nan, 0.0]), np.zeros(3)))


def test_indices_of_arrays_use_the_median_spacing():
    # 1 kHz samples with one dropped sample: dt stays 1 ms (median spacing), not the gap.
    t = np.delete(np.arange(1001) * 1e-3, 500)
    m = indices(t, np.full(len(t), 3e-6), np.full(len(t), -2.0))
    assert sample_period(t) == pytest.approx(1e-3)
    assert m.IAU == pytest.approx(2.0 * 1e-3 * len(t))
    assert m.ITAE == pytest.approx(3.0 * 1e-3 * np.sum(t))
    assert m.E_pk_um == pytest.approx(3.0)


def test_indices_agree_with_the_record_form():
    t = np.arange(2000) * 250e-6
    error = 1e-6 * np.sin(2 * np.pi * 3 * t)
    current = np.cos(2 * np.pi * 2 * t)
    assert indices(t, error, current) == compute_metrics(record(error, current))


def test_indices_refuse_arrays_of_different_lengths():
    with pytest.raises(ValueError, match="one length"):
        indices(np.arange(3.0), np.zeros(3), np.zeros(2))


def settling_record(error: np.ndarray, v_ref: np.ndarray, dt: float = 250e-6) -> RunRecord:
    columns = {
        "t": np.arange(len(error)) * dt,
        "v_ref": v_ref,
        "error": error,
        "current": np.zeros(len(error)),
    }
    return RunRecord.from_columns(columns)


@pytest.mark.parametrize("tail_um", [3.0, 10.0])
def test_settling_after_a_stop_is_the_time_an_exponential_tail_takes_into_the_band(tail_um):
    """The reference stops at 0.1 s; the error then decays as A exp(-t / tau): it enters the
    1 um band at tau ln(A) and stays."""
    dt, tau = 250e-6, 0.02
    t = np.arange(4000) * dt
    v_ref = np.where(t < 0.1, 0.01, 0.0)
    error = np.where(t < 0.1, 0.0, tail_um * 1e-6 * np.exp(-(t - 0.1) / tau))
    m = compute_metrics(settling_record(error, v_ref))
    assert m.settling_ms == pytest.approx(tau * np.log(tail_um) * 1e3, abs=0.5)  # 2 samples


def test_settling_after_a_reversal_and_without_one():
    """A reversal (the reference speed changes sign) starts a settling time as a stop does; a
    record without the reference speed, or one that never reverses nor stops, has none."""
    t = np.arange(4000) * 250e-6
    v_ref = np.where(t < 0.5, 0.01, -0.01)
    error = np.where((t >= 0.5) & (t < 0.56), 2e-6, 0.0)  # 60 ms outside the band
    assert compute_metrics(settling_record(error, v_ref)).settling_ms == pytest.approx(60, abs=0.3)
    assert compute_metrics(settling_record(error, np.full(4000, 0.01))).settling_ms is None
    assert compute_metrics(record(error, np.zeros(4000))).settling_ms is None


def test_an_error_that_never_settles_counts_the_whole_time_to_the_next_motion():
    t = np.arange(4000) * 250e-6
    v_ref = np.where((t > 0.2) & (t < 0.5), 0.0, 0.01)
    error = np.where(v_ref == 0.0, 5e-6, 0.0)  # outside the band for the whole rest
    settling = compute_metrics(settling_record(error, v_ref)).settling_ms
    assert settling == pytest.approx(300.0, abs=0.5)
