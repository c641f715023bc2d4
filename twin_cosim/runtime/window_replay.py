"""The twin on one trace window: the window's own position reference through the scenario's
controller and plant, on the one master (:func:`twin_cosim.cosim.run_scenario`), and the gap.

How a window starts. A machine in production runs one cycle again and again, and a window is one
run of it: the axis stands at rest at the reference's first position when the window begins (the
twin's plant starts there, at rest, the motor in the middle of the backlash gap, as every run of
the twin starts). A window whose reference already moves over its first samples began mid-motion:
the twin, which can only start at rest, starts at the window's first measured position, and the
samples of the first :data:`SETTLE_TIME_CONSTANTS` position-loop time constants (1 / Kp_pos) are
left out of every comparison while the twin's loop catches up; the window says so
(``starts_at_rest`` false).

The reference feeds forward its speed and acceleration: the window's samples are at the
position-loop period already, so they are the grid; a cubic spline through them gives the
derivatives (clamped to rest at an end where the reference stands still), as the interpolator
of :mod:`twin_cosim.reference` gives them for 4-ms samples.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass

import numpy as np

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.regimes import REGIMES, RegimeSettings, energy_shares
from twin_cosim.gap.data.residuals import FIELDS, Residuals, run_residuals
from twin_cosim.measured import MeasuredRun
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord
from twin_cosim.runtime.opcua import Window, check_period
from twin_cosim.scenario import Scenario

SETTLE_TIME_CONSTANTS = 5.0  # position-loop time constants left out after a start in motion
REST_SAMPLES = (
    4  # the reference stands still over this many first samples: the window starts at rest
)


@dataclass(frozen=True)
class WindowCase:
    """A window as the twin runs it.

    Attributes
    ----------
    scenario : Scenario
        The scenario with the window's reference and start position (plant parameters of the
        twin's baseline on top when given to :func:`window_case`).
    starts_at_rest : bool
        Whether the window's reference stands still at its start.
    compared : numpy.ndarray
        True at the samples every comparison uses.
    digest : str
        Of the reference and start position: windows of one digest replay alike.
    """

    scenario: Scenario
    starts_at_rest: bool
    compared: np.ndarray
    digest: str

    @property
    def grid(self) -> ReferenceGrid:
        """The window's reference on the position-loop grid."""
        return self.scenario.reference


def reference_grid(position: np.ndarray, period: float) -> ReferenceGrid:
    """The reference of a window sampled at the position-loop period ``period`` (s): its
    positions (m) with the speed (m/s) and acceleration (m/s^2) of a cubic spline through them,
    clamped to rest at an end where the reference stands still."""
    from scipy.interpolate import CubicSpline

    t = np.arange(len(position)) * period
    ends = []
    for edge in (position[:REST_SAMPLES], position[-REST_SAMPLES:]):
        at_rest = np.ptp(edge) <= RegimeSettings().v_still * period
        ends.append((1, 0.0) if at_rest else "not-a-knot")
    spline = CubicSpline(t, position, bc_type=tuple(ends))
    return ReferenceGrid(period, np.array(position, dtype=np.float64), spline(t, 1), spline(t, 2))


def window_case(scenario: Scenario, window: Window, label: str) -> WindowCase:
    """The scenario of one window: its reference, where its plant starts, what is compared.

    Raises
    ------
    WindowError
        When the window is not sampled at the scenario's position-loop period.
    """
    period = scenario.settings.position_period
    check_period(window, period, label)
    reference = window.position_reference
    grid = reference_grid(reference, period)
    starts_at_rest = bool(np.ptp(reference[:REST_SAMPLES]) <= RegimeSettings().v_still * period)
    start = float(reference[0] if starts_at_rest else window.position[0])
    compared = np.ones(window.samples, dtype=bool)
    if not starts_at_rest:
        settle = SETTLE_TIME_CONSTANTS / scenario.tuned.Kp_pos
        compared[: min(window.samples - 2, math.ceil(settle / period))] = False
    digest = hashlib.sha256(np.ascontiguousarray(reference, dtype=np.float64).tobytes())
    digest.update(repr((start, period)).encode())
    return WindowCase(
        dataclasses.replace(
            scenario,
            reference=grid,
            plant_parameters={**scenario.plant_parameters, "load_position_start": start},
            disturbance=None,
            command_disturbance=None,
        ),
        starts_at_rest,
        compared,
        digest.hexdigest()[:20],
    )


def measured_run(window: Window, label: str) -> MeasuredRun:
    """The window as a measured run (time from 0 s), as the diagnosis reads runs."""
    signals = {
        "t": window.time - window.time[0],
        "x_ref": window.position_reference,
        "x": window.position,
        "current": window.current,
    }
    if window.motor_speed is not None:
        signals["motor_speed"] = window.motor_speed
    return MeasuredRun.from_signals(label, signals)


def replay(
    plant: Plant, case: WindowCase, parameters: dict[str, float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The twin's position (m) and current (A) at the window's samples, with FMU ``parameters``
    on top of the case's scenario."""
    record = run_scenario(plant, case.scenario, plant_overrides=parameters)
    return record["x"].copy(), record["current"].copy()


def residuals(
    window: Window, case: WindowCase, plant: Plant, parameters: dict[str, float]
) -> tuple[Residuals, RunRecord]:
    """The window's residual (measured - twin) at the compared samples, and the twin's replay
    with FMU ``parameters`` on top of the case's scenario."""
    record = run_scenario(plant, case.scenario, plant_overrides=parameters)
    return residuals_against(window, case, record), record


def residuals_against(window: Window, case: WindowCase, record: RunRecord) -> Residuals:
    """The window's residual against a replay of its case, at the compared samples (regimes
    from the window's reference)."""
    run = measured_run(window, f"Sequence {window.sequence}")
    return compared_only(run_residuals(run, record, case.grid), case.compared)


def compared_only(res: Residuals, compared: np.ndarray) -> Residuals:
    """The residual at the compared samples only."""
    if compared.all():
        return res
    return Residuals(*(getattr(res, f)[compared] for f in FIELDS))


@dataclass(frozen=True)
class Gap:
    """The gap of one window against the noise floor.

    Attributes
    ----------
    position_rms_um : float
        RMS of the position residual, um.
    current_rms_ma : float
        RMS of the current residual, mA.
    position_normalised, current_normalised : float
        Those RMS over the noise floors (1: noise).
    normalised_rms : float
        sqrt(mean of the normalised energy of both signals) (1: noise).
    where : dict
        Per regime of :data:`~twin_cosim.gap.data.regimes.REGIMES`: its share of the normalised
        energy above the noise (0 to 1).
    """

    position_rms_um: float
    current_rms_ma: float
    position_normalised: float
    current_normalised: float
    normalised_rms: float
    where: dict[str, float]

    @property
    def lies(self) -> str:
        """The regime richest in the gap's energy above the noise (its enrichment)."""
        return max(self.where, key=self.where.get) if self.where else ""


def gap_of(res: Residuals, sigma_x: float, sigma_i: float) -> Gap:
    """The gap of a residual against the noise floors sigma_x (m) and sigma_i (A); where it
    lies: each regime's share of the energy above the noise, over its share of the time."""
    energy = res.normalised_energy(sigma_x, sigma_i)
    excess = np.sqrt(np.maximum(energy - 1.0, 0.0))
    shares = energy_shares(excess, res.regimes) if np.any(excess > 0) else {}
    where = {name: shares[name]["enrichment"] for name in REGIMES if name in shares}
    position_rms = float(np.sqrt(np.mean(res.position**2)))
    current_rms = float(np.sqrt(np.mean(res.current**2)))
    return Gap(
        position_rms * 1e6,
        current_rms * 1e3,
        position_rms / sigma_x,
        current_rms / sigma_i,
        float(np.sqrt(np.mean(energy))),
        where,
    )
