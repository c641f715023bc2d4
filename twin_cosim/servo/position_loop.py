"""The position loop's tests in the time domain, as a drive runs them: the step response
(``twin step``) and the following error against speed with the gain Kv (``twin kv``).

**The step** (``twin step``): the position step and settling test.

The axis stands at the scenario's start position; after :data:`BEFORE_S` the position loop's
setpoint steps by the size (the master's position injection: the reference and its
feedforwards stand still), and the run goes on for the duration. From the record, with t = 0 at
the step, x the scale reading relative to the setpoint before the step and s the step size
(the sign of the step taken as positive):

- **rise time**: from 10 % to 90 % of s (the first crossings, interpolated between samples), ms;
- **overshoot**: max(x) - s, in um and in % of s (0 when x never passes s); **peak time**: where
  the maximum lies, ms (None without overshoot);
- **settling time** to a band b (um): the first sample from which |x - s| <= b up to the end of
  the record, ms (None when the last sample is outside: not settled within the run); and the
  same to 5 % of s;
- **the tail**: what follows the 5 % settling, the slow creep of the last microns that friction
  and the integrator leave: its duration (settling to the band minus settling to 5 %, ms) and
  its largest |x - s| (um); the **final error** |x - s| at the end of the record (um).

The record (``step.csv``) has t [s], setpoint [m], x [m], error [m] (setpoint - x),
motor_speed [rad/s] and current [A] from the step on, so that each figure can be computed again
from it.

**The following error** (``twin kv``) against speed, and the position-loop gain Kv it gives.

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
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.cosim import Injections
from twin_cosim.plant import Plant
from twin_cosim.report import text_table
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario
from twin_cosim.servo.motion import level_statistics, run_motion, speed_levels, step_grid

BEFORE_S = 0.05  # s standing before the step
BAND_UM = 1.0  # um: the default settling band
COARSE_BAND = 0.05  # of the step: the band whose settling ends the transient, before the tail
COLUMNS = ("t", "setpoint", "x", "error", "motor_speed", "current")
UNITS = {
    "t": "s",
    "setpoint": "m",
    "x": "m",
    "error": "m",
    "motor_speed": "rad/s",
    "current": "A",
}


@dataclass(frozen=True)
class StepFigures:
    """What the step test reads from the record (module docstring); times in ms from the step.

    Attributes
    ----------
    size_um : float
        The step, um (signed).
    band_um : float
        The settling band, um.
    rise_time_ms : float or None
        10 % to 90 % of the step; None when x never reaches 90 %.
    peak_time_ms : float or None
        Where x is largest (in the step's direction); None without overshoot.
    overshoot_um : float
        max(x) - s, um (0 without overshoot).
    overshoot_pct : float
        The overshoot in % of the step.
    settling_time_ms : float or None
        To the band; None when not settled at the end of the record.
    settling_time_coarse_ms : float or None
        To :data:`COARSE_BAND` of the step.
    tail_ms : float or None
        Settling to the band minus settling to the coarse band.
    tail_um : float or None
        The largest |x - s| after the coarse settling, um.
    final_error_um : float
        |x - s| at the end of the record, um.
    max_current_A : float
        The largest |current|, A (at the current limit, the step is too large to be linear).
    """

    size_um: float
    band_um: float
    rise_time_ms: float | None
    peak_time_ms: float | None
    overshoot_um: float
    overshoot_pct: float
    settling_time_ms: float | None
    settling_time_coarse_ms: float | None
    tail_ms: float | None
    tail_um: float | None
    final_error_um: float
    max_current_A: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


@dataclass(frozen=True)
class StepResult:
    """A step test: its settings, record and figures.

    Attributes
    ----------
    scenario : Scenario
        The scenario (plant, controller).
    size : float
        The step, m.
    duration_s : float
        The record's length after the step, s.
    record : RunRecord
        From the step on, columns :data:`COLUMNS`.
    figures : StepFigures
        What the test reads from it.
    """

    scenario: Scenario
    size: float
    duration_s: float
    record: RunRecord
    figures: StepFigures

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the figures, the test's settings, the controller."""
        limit = self.scenario.settings.current_limit
        return {
            "scenario": str(self.scenario.source),
            "step_mm": self.size * 1e3,
            "duration_s": self.duration_s,
            **self.figures.as_dict(),
            "current_limit_A": limit,
            "current_limited": self.figures.max_current_A >= limit * (1 - 1e-9),
            "params": self.scenario.tuned.as_dict(),
        }


def step_test(
    plant: Plant, scenario: Scenario, size: float, duration_s: float, band_um: float = BAND_UM
) -> StepResult:
    """Run the step test of ``scenario``'s axis: a step of ``size`` (m) held ``duration_s``
    (s), settling to ``band_um`` (um).

    Raises
    ------
    ValueError
        On a zero step, a duration or band that is not positive.
    """
    if not (math.isfinite(size) and size != 0.0):
        raise ValueError(f"--size: expected a step other than 0 mm, got {size * 1e3:g}")
    if not duration_s > 0 or not band_um > 0:
        raise ValueError("the duration and the band must be above 0")
    settings = scenario.settings
    period = settings.position_period
    start = float(scenario.reference.position[0])
    grid = step_grid(BEFORE_S + duration_s, period, start)
    at = round(BEFORE_S / period)
    offset = np.where(np.arange(len(grid.position)) >= at, size, 0.0)
    recorded = run_motion(
        plant,
        grid,
        scenario.tuned,
        settings,
        scenario.plant_parameters,
        Injections(position=offset),
    ).position_loop
    after = slice(at, None)
    record = RunRecord.from_columns(
        {
            "t": np.asarray(recorded["t"])[after] - at * period,
            "setpoint": grid.position[after] + size,
            "x": np.asarray(recorded["x"])[after],
            "error": np.asarray(recorded["error"])[after],
            "motor_speed": np.asarray(recorded["motor_speed"])[after],
            "current": np.asarray(recorded["current"])[after],
        },
        UNITS,
    )
    figures = step_figures(record, start, size, band_um)
    return StepResult(scenario, size, duration_s, record, figures)


def step_figures(record: RunRecord, start: float, size: float, band_um: float) -> StepFigures:
    """The figures of a step record (columns t [s], x [m], current [A]) of a step of ``size``
    (m) from the setpoint ``start`` (m), settling to ``band_um`` (um)."""
    t = np.asarray(record["t"])
    direction = math.copysign(1.0, size)
    moved = (np.asarray(record["x"]) - start) * direction  # m, positive in the step's direction
    s = abs(size)
    deviation_um = np.abs(moved - s) * 1e6
    peak = int(np.argmax(moved))
    coarse = settling_index(deviation_um, COARSE_BAND * s * 1e6)
    fine = settling_index(deviation_um, band_um)
    rise = None
    low, high = _first_crossing(t, moved, 0.1 * s), _first_crossing(t, moved, 0.9 * s)
    if low is not None and high is not None:
        rise = (high - low) * 1e3
    overshoot = max(0.0, float(moved[peak]) - s)
    fine_ms = None if fine is None else float(t[fine]) * 1e3
    coarse_ms = None if coarse is None else float(t[coarse]) * 1e3
    return StepFigures(
        size_um=size * 1e6,
        band_um=band_um,
        rise_time_ms=rise,
        peak_time_ms=float(t[peak]) * 1e3 if overshoot > 0 else None,
        overshoot_um=overshoot * 1e6,
        overshoot_pct=100.0 * overshoot / s,
        settling_time_ms=fine_ms,
        settling_time_coarse_ms=coarse_ms,
        tail_ms=None if fine_ms is None or coarse_ms is None else fine_ms - coarse_ms,
        tail_um=None if coarse is None else float(deviation_um[coarse:].max()),
        final_error_um=float(deviation_um[-1]),
        max_current_A=float(np.max(np.abs(np.asarray(record["current"])))),
    )


def settling_index(deviation: np.ndarray, band: float) -> int | None:
    """The first sample from which ``deviation`` stays within ``band`` to the end (None when
    the last sample lies outside)."""
    outside = np.flatnonzero(deviation > band)
    if not len(outside):
        return 0
    last = int(outside[-1])
    return None if last == len(deviation) - 1 else last + 1


def _first_crossing(t: np.ndarray, values: np.ndarray, level: float) -> float | None:
    """The first time (s) ``values`` reaches ``level``, interpolated between samples."""
    above = np.flatnonzero(values >= level)
    if not len(above):
        return None
    i = int(above[0])
    if i == 0:
        return float(t[0])
    share = (level - values[i - 1]) / (values[i] - values[i - 1])
    return float(t[i - 1] + share * (t[i] - t[i - 1]))


def describe_step(result: StepResult) -> str:
    """The figures as a short table with units (``step.txt``)."""
    f = result.figures

    def ms(value: float | None) -> str:
        return "not settled" if value is None else f"{value:.2f}"

    rows = [
        ("step", f"{f.size_um:.4g}", "um"),
        ("rise time 10-90 %", "-" if f.rise_time_ms is None else f"{f.rise_time_ms:.2f}", "ms"),
        ("peak time", "-" if f.peak_time_ms is None else f"{f.peak_time_ms:.2f}", "ms"),
        ("overshoot", f"{f.overshoot_um:.3g} ({f.overshoot_pct:.2f} %)", "um"),
        (f"settling time to +-{f.band_um:g} um", ms(f.settling_time_ms), "ms"),
        (f"settling time to +-{COARSE_BAND * 100:g} %", ms(f.settling_time_coarse_ms), "ms"),
        ("tail: duration", ms(f.tail_ms), "ms"),
        ("tail: largest deviation", "-" if f.tail_um is None else f"{f.tail_um:.3g}", "um"),
        ("final error", f"{f.final_error_um:.4f}", "um"),
        ("largest current", f"{f.max_current_A:.3g}", "A"),
    ]
    return text_table(("figure", "value", "unit"), rows)


def plot_step(result: StepResult, path: Path, command: str) -> Path:
    """The response and its deviation from the target (linear, then log scale to show the
    tail), the settling band and times marked; returns ``path``."""
    from twin_cosim.plots import save_figure, stacked_axes

    f = result.figures
    t_ms = np.asarray(result.record["t"]) * 1e3
    start = float(result.record["setpoint"][0]) - result.size
    moved_um = (np.asarray(result.record["x"]) - start) * 1e6
    deviation_um = np.abs(moved_um - f.size_um)
    fig, axes = stacked_axes(3, (9, 9), [3, 2, 2])
    axes[0].plot(t_ms, moved_um, lw=1.0, label="scale reading x")
    axes[0].axhline(f.size_um, color="grey", lw=0.8, ls="--", label="setpoint")
    for sign in (-1, 1):
        axes[0].axhline(f.size_um + sign * f.band_um, color="tab:green", lw=0.6, ls=":")
    axes[0].set_ylabel("x - x before the step [um]")
    axes[1].plot(t_ms, moved_um - f.size_um, lw=1.0, color="tab:orange")
    axes[1].axhspan(
        -f.band_um, f.band_um, color="tab:green", alpha=0.15, label=f"+-{f.band_um:g} um"
    )
    axes[1].set_ylim(-5 * f.band_um - f.overshoot_um, 5 * f.band_um + f.overshoot_um)
    axes[1].set_ylabel("x - setpoint [um]")
    axes[2].semilogy(t_ms, np.maximum(deviation_um, 1e-4), lw=1.0, color="tab:orange")
    axes[2].axhline(f.band_um, color="tab:green", lw=0.8, ls=":")
    axes[2].set_ylabel("|x - setpoint| [um]")
    axes[2].set_xlabel("time after the step [ms]")
    for value, label, color in (
        (f.settling_time_coarse_ms, f"settled to {COARSE_BAND * 100:g} %", "tab:purple"),
        (f.settling_time_ms, f"settled to {f.band_um:g} um", "tab:green"),
    ):
        if value is not None:
            for ax in axes:
                ax.axvline(value, color=color, lw=0.8, ls="--")
            axes[0].plot([], [], color=color, ls="--", lw=0.8, label=f"{label}: {value:.1f} ms")
    settled = "not settled" if f.settling_time_ms is None else f"{f.settling_time_ms:.1f} ms"
    axes[0].set_title(
        f"rise {f.rise_time_ms or math.nan:.1f} ms, overshoot {f.overshoot_pct:.1f} % "
        f"({f.overshoot_um:.3g} um), settling to {f.band_um:g} um {settled}, tail "
        f"{f.tail_um or 0.0:.3g} um",
        fontsize=9,
    )
    fig.suptitle(
        f"{result.scenario.name}: position step of {f.size_um:.4g} um\n{command}", fontsize=9
    )
    axes[0].legend(fontsize=8, loc="lower right")
    axes[1].legend(fontsize=8, loc="upper right")
    return save_figure(fig, axes, path)


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


def describe_following(result: FollowingResult) -> str:
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
