"""The twin on a window: the reference's derivatives, where the twin starts, and the gap of the
twin against a noise-free run of itself (nothing but the start assumption between them)."""

from __future__ import annotations

import numpy as np
import pytest
from runtime_cases import cycle

from twin_cosim.plant import Plant
from twin_cosim.runtime.opcua import Window
from twin_cosim.runtime.virtual_machine import draw_machine
from twin_cosim.runtime.window_replay import (
    gap_of,
    reference_grid,
    residuals,
    window_case,
)


def test_the_reference_grid_gives_the_derivatives_of_a_smooth_motion() -> None:
    period = 250e-6
    t = np.arange(4001) * period
    position = 0.002 * (1 - np.cos(2 * np.pi * t))  # starts and ends at rest
    grid = reference_grid(position, period)
    inner = slice(20, -20)
    speed = 0.004 * np.pi * np.sin(2 * np.pi * t)
    acceleration = 0.008 * np.pi**2 * np.cos(2 * np.pi * t)
    assert np.max(np.abs(grid.velocity - speed)[inner]) < 1e-9
    assert np.max(np.abs(grid.acceleration - acceleration)[inner]) < 1e-5
    assert abs(grid.velocity[0]) < 1e-9


def test_a_window_that_starts_moving_leaves_out_the_settling_samples(tmp_path) -> None:
    scenario = cycle(tmp_path)
    n = 2000
    t = np.arange(n) * scenario.settings.position_period
    at_rest = Window(1, t, np.zeros(n), np.zeros(n), np.zeros(n))
    moving = Window(2, t, 0.01 * t, 1e-6 + 0.01 * t, np.zeros(n))
    rest_case, moving_case = (window_case(scenario, w, "w") for w in (at_rest, moving))
    assert rest_case.starts_at_rest and rest_case.compared.all()
    assert not moving_case.starts_at_rest
    settle = 5.0 / scenario.tuned.Kp_pos  # five position-loop time constants
    assert (~moving_case.compared).sum() == pytest.approx(settle / 250e-6, abs=1)
    assert moving_case.scenario.plant_parameters["load_position_start"] == 1e-6


def noise_free_residuals(folder):
    """The twin's residual against a noise-free window of itself (an exact machine)."""
    scenario = cycle(folder)
    machine = draw_machine(
        scenario, str(scenario.plant_fmu()), [], [], noise_position=0.0, noise_current=0.0
    )
    window = machine.window(0)
    case = window_case(scenario, window, "window 0")
    with Plant(scenario.plant_fmu()) as plant:
        return residuals(window, case, plant, {})[0]


def test_the_twin_against_a_noise_free_run_of_itself_has_no_gap(tmp_path) -> None:
    res = noise_free_residuals(tmp_path)
    assert np.max(np.abs(res.position)) < 1e-12 and np.max(np.abs(res.current)) < 1e-9
    gap = gap_of(res, 20e-9, 5e-3)
    assert gap.normalised_rms < 1e-3 and gap.where == {}


def test_where_the_gap_lies_is_the_regime_of_a_residual_put_there(tmp_path) -> None:
    res = noise_free_residuals(tmp_path)
    bumped = res.minus(res.position, np.where(res.regimes == 4, 0.05, 0.0))  # reversal
    gap = gap_of(bumped, 20e-9, 5e-3)
    assert gap.lies == "reversal" and gap.current_normalised > 1


def test_a_reference_at_rest_at_its_ends_is_clamped_there() -> None:
    move = 1e-3 * np.sin(np.linspace(0.0, np.pi / 2, 400)) ** 2
    position = np.concatenate([np.zeros(50), move, np.full(50, 1e-3)])
    grid = reference_grid(position, 250e-6)
    assert grid.velocity[0] == 0.0 and grid.velocity[-1] == 0.0
