"""The twin's model error and the bounds it sets on the figures of merit of one run."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.metrics import indices
from twin_cosim.model_error import ModelError

DT = 0.001  # s
T = np.arange(0.0, 4.0, DT)  # s: a 4 s metrics window


def _twin_run(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A tracking error (m) and a current (A) of a twin: reversals and noise."""
    error = 3e-6 * np.sin(2 * np.pi * 0.7 * T) + 2e-7 * rng.standard_normal(T.size)
    current = 0.8 * np.sign(np.sin(2 * np.pi * 0.5 * T)) + 0.05 * rng.standard_normal(T.size)
    return error, current


@pytest.mark.parametrize("seed", range(5))
def test_the_margins_bound_the_machine_figures_on_the_same_run(seed):
    """A machine that differs from the twin by a discrepancy of any shape (here a friction-like
    step at each reversal, a slow drift and noise): each of its figures lies within the margin
    the discrepancy sets of the twin's."""
    rng = np.random.default_rng(seed)
    error, current = _twin_run(rng)
    dx = (
        1e-6 * rng.uniform(0.2, 2.0) * np.sign(np.cos(2 * np.pi * 0.7 * T))
        + 4e-7 * T
        + 5e-8 * rng.standard_normal(T.size)
    )
    di = 0.1 * rng.uniform(0.2, 2.0) * np.sign(np.cos(2 * np.pi * 0.5 * T))
    di += 0.01 * rng.standard_normal(T.size)
    # the machine's scale reads x_machine = x_twin + dx: its tracking error is e - dx
    twin, machine = indices(T, error, current), indices(T, error - dx, current + di)
    margins = ModelError.of_discrepancy(dx, di).margins(T.size * DT)  # N samples of DT
    assert abs(machine.E_pk_um - twin.E_pk_um) <= margins["E_pk_um"]
    assert abs(machine.ITAE - twin.ITAE) <= margins["ITAE"]
    assert abs(machine.IAU - twin.IAU) <= margins["IAU"]


def test_the_peak_margin_is_reached_by_a_constant_offset():
    """A tracking error of one sign and a constant discrepancy that adds to it: the machine's
    E_pk is the twin's plus the offset, the margin exactly."""
    error = 2e-6 * np.abs(np.sin(2 * np.pi * 0.3 * T))
    current = np.ones_like(T)
    dx = np.full_like(T, -5e-7)
    twin, machine = indices(T, error, current), indices(T, error - dx, current)
    margin = ModelError.of_discrepancy(dx, np.zeros_like(T)).margins(4.0)["E_pk_um"]
    assert machine.E_pk_um - twin.E_pk_um == pytest.approx(margin, rel=1e-9)
    assert margin == pytest.approx(0.5)


@pytest.mark.parametrize("samples", [11, 101])
def test_the_integral_margins_hold_in_the_worst_case_over_n_samples(samples):
    """The worst cases of the integral bounds over a short window, each in the figure's own
    sign: a position discrepancy growing with t - t_0 (ITAE), a constant current discrepancy
    (IAU). ITAE and IAU lie within their margins when the window counts its N samples (N dt),
    beyond them with the span (N - 1) dt alone."""
    t = np.arange(samples) * DT
    error, current = 1e-6 * np.ones_like(t), np.ones_like(t)
    dx, di = -1e-7 * t / t[-1], np.full_like(t, 0.1)
    twin, machine = indices(t, error, current), indices(t, error - dx, current + di)
    found = ModelError.of_discrepancy(dx, di)
    counted, spanned = found.margins(samples * DT), found.margins(float(t[-1]))
    for name in ("ITAE", "IAU"):
        gap = abs(getattr(machine, name) - getattr(twin, name))
        assert gap <= counted[name] * (1 + 1e-12)  # IAU's worst case reaches it exactly
        assert gap > spanned[name]


def test_the_integral_margins_follow_the_window_length():
    """ITAE's margin T^2 / sqrt(3) RMS(dx) and IAU's T RMS(di), in um.s^2 and A.s."""
    error = ModelError(position_peak_m=2e-7, position_rms_m=1e-7, current_rms_A=0.004)
    margins = error.margins(9.0)
    assert margins["E_pk_um"] == pytest.approx(0.2)
    assert margins["ITAE"] == pytest.approx(81.0 / math.sqrt(3.0) * 0.1)
    assert margins["IAU"] == pytest.approx(0.036)


def test_white_noise_gives_its_sigma_as_rms():
    rng = np.random.default_rng(7)
    error = ModelError.of_discrepancy(
        20e-9 * rng.standard_normal(40_000), 5e-3 * rng.standard_normal(40_000)
    )
    assert error.position_rms_m == pytest.approx(20e-9, rel=0.03)
    assert error.current_rms_A == pytest.approx(5e-3, rel=0.03)
    assert 3 * 20e-9 < error.position_peak_m < 6 * 20e-9


@pytest.mark.parametrize(
    "position, current",
    [(np.array([]), np.array([0.1])), (np.array([1e-6, np.nan]), np.array([0.1, 0.1]))],
)
def test_empty_or_non_finite_discrepancies_are_refused(position, current):
    with pytest.raises(ValueError, match="non-empty and finite"):
        ModelError.of_discrepancy(position, current)


@pytest.mark.parametrize("window", [0.0, -1.0, math.inf, math.nan])
def test_a_window_that_is_no_length_is_refused(window):
    with pytest.raises(ValueError, match="metrics window"):
        ModelError(1e-7, 1e-8, 0.01).margins(window)
