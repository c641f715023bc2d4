"""Margins and closed-loop figures against analytic loops; figures read where the coherence is
below the floor are withheld (issue 31, item 2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.frequency.margins import margins_of_data, open_loop_of

F = np.geomspace(0.5, 500.0, 2000)


def second_order(w_n: float, zeta: float) -> np.ndarray:
    """L = w_n^2 / (s (s + 2 zeta w_n)): its closed loop is the standard second order."""
    s = 2j * np.pi * F
    return w_n**2 / (s * (s + 2 * zeta * w_n))


def test_closed_loop_figures_of_a_second_order_loop_are_the_textbook_ones():
    w_n, zeta = 2 * math.pi * 20.0, 0.3
    m = margins_of_data(F, second_order(w_n, zeta))
    peak = 1 / (2 * zeta * math.sqrt(1 - zeta**2))  # M_r at w_n sqrt(1 - 2 zeta^2)
    assert m.resonance_peak_db == pytest.approx(20 * math.log10(peak), abs=0.01)
    assert m.resonance_peak_hz == pytest.approx(20 * math.sqrt(1 - 2 * zeta**2), rel=0.005)
    x = 1 - 2 * zeta**2
    bandwidth = 20 * math.sqrt(x + math.sqrt(x**2 + 1))  # |T| = 1/sqrt(2)
    assert m.bandwidth_hz == pytest.approx(bandwidth, rel=0.005)
    crossover = 20 * math.sqrt(math.sqrt(1 + 4 * zeta**4) - 2 * zeta**2)
    assert m.crossover_hz == pytest.approx(crossover, rel=0.005)
    pm = math.degrees(math.atan(2 * zeta / math.sqrt(math.sqrt(1 + 4 * zeta**4) - 2 * zeta**2)))
    assert m.phase_margin_deg == pytest.approx(pm, abs=0.05)
    s = 1 / (1 + second_order(w_n, zeta))
    assert m.peak_sensitivity_db == pytest.approx(20 * np.log10(np.abs(s).max()), abs=1e-9)


@pytest.mark.parametrize("kind", ["closed", "sensitivity"])
def test_the_open_loop_of_a_closed_loop_or_sensitivity_is_the_loop(kind):
    loop = second_order(2 * math.pi * 15.0, 0.4)
    response = loop / (1 + loop) if kind == "closed" else 1 / (1 + loop)
    np.testing.assert_allclose(open_loop_of(kind, response), loop, rtol=1e-9)


def test_a_margin_read_above_an_incoherent_line_is_withheld_with_what_was_read():
    loop = second_order(2 * math.pi * 20.0, 0.3)
    coherent = margins_of_data(F, loop, np.ones(len(F)))
    assert coherent.withheld == {} and coherent.phase_margin_deg is not None
    coherence = np.where((F > 3.0) & (F < 4.0), 0.5, 0.99)  # a drop below the crossover
    m = margins_of_data(F, loop, coherence)
    for name in ("phase_margin_deg", "bandwidth_hz", "resonance_peak_db", "peak_sensitivity_db"):
        assert getattr(m, name) is None
        assert m.withheld[name]["lowest_coherence"] == 0.5
    assert m.withheld["phase_margin_deg"]["value"] == pytest.approx(coherent.phase_margin_deg)
    assert m.crossover_hz is None
    above = margins_of_data(F, loop, np.where(F > 200.0, 0.3, 0.99))  # only above the figures
    assert above.withheld == {} and above.phase_margin_deg == coherent.phase_margin_deg
