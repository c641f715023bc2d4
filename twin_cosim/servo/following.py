"""``twin kv``: the following error against speed, and the position-loop gain Kv it gives.

At a constant speed v the P position loop needs an error e to command the speed: with the
speed loop's integrator holding the speed exactly (no droop from friction), Kp_pos e + ff v = v,
so e = (1 - ff) v / Kp_pos with ff the velocity feedforward gain. A CNC's Kv is v / e with the
velocity feedforward off: the position loop's gain as the machine shows it, in 1/s (or, as
machine tool builders quote it, in (m/min)/mm: 1/s times 0.06).

The test runs the axis through levels of constant speed in both directions
(:func:`~twin_cosim.servo.motion.speed_levels`; by default :data:`LEVEL_SHARES` of the
scenario's fastest reference speed), once with the velocity feedforward off, which gives Kv
(the least-squares slope of v against e over all levels, v = Kv e), and once with the
scenario's feedforward, which gives the following error the axis actually runs with. The
error is the mean of x_ref - x over each level's steady window.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.plant import Plant
from twin_cosim.report import text_table
from twin_cosim.scenario import Scenario
from twin_cosim.servo.motion import level_statistics, run_motion, speed_levels

LEVEL_SHARES = (0.125, 0.25, 0.5, 1.0)  # of the scenario's fastest reference speed
DWELL_S = 0.3  # s at each level
KV_M_MIN_PER_MM = 0.06  # (m/min)/mm per 1/s


@dataclass(frozen=True)
class FollowingLevel:
    """The following error at one constant speed.

    Attributes
    ----------
    speed_m_s : float
        Carriage speed, m/s (signed).
    error_um : float
        Mean x_ref - x, velocity feedforward off, um.
    error_with_feedforward_um : float
        The same with the scenario's velocity feedforward, um.
    kv_per_s : float
        v / e with the feedforward off, 1/s.
    """

    speed_m_s: float
    error_um: float
    error_with_feedforward_um: float
    kv_per_s: float


@dataclass(frozen=True)
class FollowingResult:
    """The following-error test of a scenario's axis.

    Attributes
    ----------
    scenario : Scenario
        The scenario (plant, controller).
    levels : list of FollowingLevel
        Each level, positive speeds then negative.
    kv_per_s : float
        The least-squares Kv over all levels, 1/s.
    """

    scenario: Scenario
    levels: list[FollowingLevel]
    kv_per_s: float

    def summary(self) -> dict[str, Any]:
        """JSON-ready: Kv, the position gain it is compared with, each level."""
        kp = self.scenario.tuned.Kp_pos
        return {
            "scenario": str(self.scenario.source),
            "kv_per_s": self.kv_per_s,
            "kv_m_min_per_mm": self.kv_per_s * KV_M_MIN_PER_MM,
            "position_gain_per_s": kp,
            "kv_over_position_gain": self.kv_per_s / kp,
            "velocity_feedforward": self.scenario.settings.ff_velocity,
            "levels": [dataclasses.asdict(level) for level in self.levels],
            "params": self.scenario.tuned.as_dict(),
        }


def default_speeds(scenario: Scenario) -> list[float]:
    """:data:`LEVEL_SHARES` of the scenario's fastest reference speed, m/s."""
    fastest = float(np.max(np.abs(scenario.reference.velocity)))
    if not fastest > 0:
        raise ValueError(
            f"{scenario.source}: the reference never moves; give the speeds (--speeds)"
        )
    return [share * fastest for share in LEVEL_SHARES]


def following_test(
    plant: Plant, scenario: Scenario, speeds: list[float] | None = None, dwell_s: float = DWELL_S
) -> FollowingResult:
    """Measure the following error of ``scenario``'s axis at ``speeds`` (m/s, magnitudes; by
    default :func:`default_speeds`) in both directions, each held ``dwell_s`` (s).

    Raises
    ------
    ValueError
        On a speed that is not above 0.
    """
    speeds = sorted(speeds or default_speeds(scenario), reverse=True)
    if not all(v > 0 for v in speeds):
        raise ValueError(f"--speeds: expected speeds above 0 m/s, got {speeds}")
    settings = scenario.settings
    start = float(scenario.reference.position[0])
    errors = {}
    for feedforward in (0.0, settings.ff_velocity):
        chosen = dataclasses.replace(settings, ff_velocity=feedforward)
        for sign in (1.0, -1.0):
            grid, levels = speed_levels(
                [sign * v for v in speeds], dwell_s, settings.position_period, start
            )
            record = run_motion(
                plant, grid, scenario.tuned, chosen, scenario.plant_parameters
            ).position_loop
            errors[feedforward, sign], _ = level_statistics(record, levels, "error")
    levels = []
    for sign in (1.0, -1.0):
        for v, off, on in zip(
            speeds, errors[0.0, sign], errors[settings.ff_velocity, sign], strict=True
        ):
            levels.append(FollowingLevel(sign * v, off * 1e6, on * 1e6, sign * v / off))
    v = np.array([level.speed_m_s for level in levels])
    e = np.array([level.error_um for level in levels]) * 1e-6
    return FollowingResult(scenario, levels, float(np.sum(v * v) / np.sum(v * e)))


def describe(result: FollowingResult) -> str:
    """The levels and Kv as a short table with units (``kv.txt``)."""
    rows = [
        (
            f"{level.speed_m_s * 1e3:+.4g}",
            f"{level.speed_m_s * 6e4:+.5g}",
            f"{level.error_um:+.4g}",
            f"{level.kv_per_s:.5g}",
            f"{level.error_with_feedforward_um:+.3g}",
        )
        for level in result.levels
    ]
    summary = result.summary()
    table = text_table(
        (
            "speed [mm/s]",
            "speed [mm/min]",
            "error, ff off [um]",
            "v/e [1/s]",
            f"error, ff {result.scenario.settings.ff_velocity:g} [um]",
        ),
        rows,
    )
    return table + (
        f"Kv {summary['kv_per_s']:.5g} 1/s ({summary['kv_m_min_per_mm']:.4g} (m/min)/mm); "
        f"Kp_pos {summary['position_gain_per_s']:.5g} 1/s; Kv / Kp_pos "
        f"{summary['kv_over_position_gain']:.5f}\n"
    )


def plot_following(result: FollowingResult, path: Path, command: str) -> Path:
    """The following error against speed, both directions, feedforward off and on, with the
    line v / Kp_pos; returns ``path``."""
    from twin_cosim.plots import save_figure, stacked_axes

    v = np.array([level.speed_m_s for level in result.levels]) * 1e3
    off = np.array([level.error_um for level in result.levels])
    on = np.array([level.error_with_feedforward_um for level in result.levels])
    kp = result.scenario.tuned.Kp_pos
    fig, axes = stacked_axes(2, (8, 7), [3, 2])
    line = np.linspace(v.min(), v.max(), 50)
    axes[0].plot(line, line * 1e3 / kp, color="grey", lw=1.0, label=f"v / Kp_pos ({kp:.4g} 1/s)")
    axes[0].plot(v, off, "o", label=f"measured, feedforward off: Kv {result.kv_per_s:.4g} 1/s")
    axes[0].set_ylabel("following error x_ref - x [um]")
    axes[0].legend(fontsize=8)
    ff = result.scenario.settings.ff_velocity
    axes[1].plot(v, on, "s", color="tab:orange", label=f"velocity feedforward {ff:g}")
    axes[1].axhline(0.0, color="grey", lw=0.8)
    axes[1].set_ylabel("following error [um]")
    axes[1].set_xlabel("carriage speed [mm/s]")
    axes[1].legend(fontsize=8)
    fig.suptitle(f"{result.scenario.name}: following error against speed\n{command}", fontsize=9)
    return save_figure(fig, axes, path)
