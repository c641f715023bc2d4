"""The information model's window: what a client accepts, and what it refuses, naming it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.runtime.information_model import (
    WindowError,
    check_period,
    sequence_gap,
    window_of,
)


def arrays(n: int = 100, period: float = 250e-6) -> dict[str, list[float]]:
    t = 3.0 + np.arange(n) * period  # the window's own clock need not start at 0
    return {
        "time": t.tolist(),
        "position_reference": np.linspace(0, 1e-3, n).tolist(),
        "position": np.linspace(0, 1e-3, n).tolist(),
        "current": np.zeros(n).tolist(),
    }


def test_a_window_without_motor_speed_is_read_with_its_period_and_duration() -> None:
    window = window_of(5, arrays(), "window 0 (Sequence 5)")
    assert window.motor_speed is None and window.samples == 100
    assert math.isclose(window.period, 250e-6) and math.isclose(window.duration, 0.025)
    assert set(window.arrays()) == {"time", "position_reference", "position", "current"}


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (lambda a: a.update(current=a["current"][:-1]), "unequal length"),
        (lambda a: a["position"].__setitem__(7, float("nan")), "position holds 1 NaN"),
        (lambda a: a.pop("current"), "no array 'current'"),
        (lambda a: a["time"].__setitem__(50, a["time"][50] + 1e-4), "regular step"),
        (lambda a: a.update(motor_speed=[0.0] * 99), "unequal length"),
    ],
)
def test_a_bad_window_is_refused_naming_the_window_and_the_array(change, expected) -> None:
    data = arrays()
    change(data)
    with pytest.raises(WindowError, match=expected) as raised:
        window_of(9, data, "window 4 (Sequence 9)")
    assert "window 4 (Sequence 9)" in str(raised.value)


def test_a_window_not_sampled_at_the_position_loop_period_is_refused() -> None:
    window = window_of(1, arrays(period=1e-3), "window 0")
    with pytest.raises(WindowError, match="1000 us.*250 us"):
        check_period(window, 250e-6, "window 0")
    check_period(window_of(1, arrays(), "window 0"), 250e-6, "window 0")


def test_sequence_gaps_count_the_windows_between_and_wrap_as_a_uint32() -> None:
    assert sequence_gap(4, 5) == 0
    assert sequence_gap(4, 8) == 3
    assert sequence_gap(2**32 - 1, 0) == 0
    assert sequence_gap(2**32 - 2, 1) == 2
