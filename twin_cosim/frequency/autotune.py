"""``twin autotune``: an FRF auto-tuner, the way an industrial tuner sets a drive.

From the plant's FRF (a file, or measured on the twin at an operating speed with a small
excitation, so that friction slides and backlash stays closed) the two-mass model is fitted
(:mod:`twin_cosim.frequency.calibration`); the design model is that plant, its delay in whole
speed-loop periods, held at the speed-loop period (:mod:`twin_cosim.frequency.linear`). Then:

1. **speed loop**: the rigid-body rule Kp_vel = (J_M + J_L) w_c / K_t for a crossover w_c and an
   integral time T_n = alpha / w_c (Ki_vel = Kp_vel T / T_n per sample, T the speed-loop
   period), on a grid of w_c and for each current-filter chain: none, or a notch on the first
   resonance f_02 (its depth the resonance's rise over the rigid-body line, its bandwidth a
   quarter or a half of f_02). The phase margin is a **target**: on a rigid body the PI's lag at
   the crossover, atan(1 / alpha), sets it, so alpha is the one that gives the target
   (:func:`integral_factor`, within :data:`TARGET_TOLERANCE_DEG`). A design is admissible when
   its loop reaches the target and keeps :data:`GAIN_MARGIN_DB` and
   :data:`PEAK_SENSITIVITY_DB`, and the loop with the motor alone (the backlash open: the loop
   gain rises by (J_M + J_L) / J_M) keeps them and at least the target. When no crossover can
   reach the target the command says which phase margins the grid reaches. Fed back from the
   motor speed, a two-mass
   resonance is phase-stabilised (collocated: the plant's phase stays within +-90 degrees)
   until lags (current loop, dead time, the hold, a filter) eat that phase at the resonance;
   that is where a notch is needed, and where only the notched designs stay admissible;
2. **position loop**: for each admissible speed design, the highest Kp_pos whose loop (the speed
   loop closed inside, lifted to the position-loop period) keeps
   :data:`POSITION_PHASE_MARGIN_DEG`, :data:`POSITION_GAIN_MARGIN_DB` and a closed-loop peak of
   at most :data:`POSITION_PEAK_DB` (no overshoot to speak of), read in one pass from the loop
   at Kp_pos = 1 (:func:`position_gain_limit`), and whose closed-loop -3 dB bandwidth stays at
   or below the speed loop's (the outer loop no faster than the inner one,
   :func:`bandwidth_gain_limit`); the set says which of these limits Kp_pos. The design of the
   highest Kp_pos wins (the
   machine-tool tuner's figure: the following error is v / Kp_pos), then the higher integral
   gain (stiffer against load torques), then the higher crossover;
3. **feedforwards**: velocity and acceleration at gain 1, the acceleration's inertia the fitted
   J_M + J_L.

PP2, PP3 and f_H, the reversal compensation, stay the scenario's: no frequency response
measures them. The set's margins are read from the design loops' responses on a dense grid up to
the Nyquist frequency (as :func:`~twin_cosim.frequency.margins.margins_of_data` reads them,
which agrees with python-control; tested); its metrics come from a run of the scenario.

On a scenario (:func:`autotune_scenario`), the plant FRF is a file or measured on the twin as a
tuner takes it on a machine with friction and backlash: at an operating motor speed of
:data:`~twin_cosim.frequency.measurement.OPERATING_MOTOR_SPEED` (friction slides in one
direction, the backlash stays closed) with a multisine of
:data:`~twin_cosim.frequency.measurement.EXCITATION_SHARE` of the current limit (small enough not
to open the backlash), the nonlinearities on: ``twin bode``'s default operating point; the
proposed set runs on the scenario beside the scenario's own.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.controller_set import ControllerSet
from twin_cosim.cosim import run_scenario
from twin_cosim.current_filters import Notch
from twin_cosim.frequency.bode import plot_bode
from twin_cosim.frequency.calibration import (
    DEFAULT_COHERENCE_FLOOR,
    TwoMassFit,
    fit_two_mass,
    read_frf,
)
from twin_cosim.frequency.linear import Discrete, LinearLoops, TwoMass, hold_discretised
from twin_cosim.frequency.margins import (
    Margins,
    dense_grid,
    margins_of_data,
    phase_margin_of,
)
from twin_cosim.frequency.margins import bandwidth_hz as bandwidth_of
from twin_cosim.frequency.measurement import (
    PLANT_BAND,
    FrequencyResponse,
    MeasurementSettings,
    default_amplitude,
    measure,
)
from twin_cosim.metrics import compute_metrics
from twin_cosim.plant import Plant
from twin_cosim.scenario import Scenario, with_controller_set

PHASE_MARGIN_DEG = 50.0  # default target of the speed loop, deg
GAIN_MARGIN_DB = 10.0
PEAK_SENSITIVITY_DB = 6.0
POSITION_PHASE_MARGIN_DEG = 60.0
POSITION_PEAK_DB = 1.0
POSITION_GAIN_MARGIN_DB = 6.0
INTEGRAL_FACTOR_RANGE = (0.3, 100.0)  # alpha, T_n = alpha / w_c: where the target is sought
BISECTIONS = 12  # halvings of log(alpha): alpha within 0.15 % of its value at the target
TARGET_TOLERANCE_DEG = 0.5  # the speed loop's phase margin lies within this of its target
NOTCH_WIDTHS = (0.25, 0.5)  # bandwidth over the resonance frequency f_02
NOTCH_DEPTH_DB = (-40.0, -6.0)  # the notch's depth is kept within these
CROSSOVERS = 30  # crossover frequencies tried, log-spaced from MIN_CROSSOVER_HZ
MIN_CROSSOVER_HZ = 5.0
MAX_CROSSOVER = 0.2  # of the speed loop's Nyquist frequency
LOW_HZ = 0.5  # lowest frequency of the design grid
GRID_GUARD = 0.98  # the position gain stays this share below its limit read on the grid
DESIGN_POINTS = 1500  # frequencies of the design grid, log-spaced up to the Nyquist frequency


@dataclass(frozen=True)
class SpeedDesign:
    """One speed-loop design: its gains, filters and margins on the design model."""

    Kp_vel: float
    Ki_vel: float
    filters: tuple[current_filters.CurrentFilter, ...]
    margins: Margins


@dataclass(frozen=True)
class Autotuned:
    """What the tuner proposes and why.

    Attributes
    ----------
    controller_set : ControllerSet
        The six parameters and the settings it sets (filters, feedforwards).
    fit : TwoMassFit
        The plant fitted to the FRF.
    speed_margins : Margins
        Of the speed loop on the design model.
    position_margins : Margins
        Of the position loop on the design model.
    phase_margin_target : float
        The speed loop's phase-margin target, degrees.
    position_limit : str
        What limits Kp_pos: a margin of the position loop, or the speed loop's bandwidth.
    source : str
        Where the FRF came from.
    wall_s : float
        The tuner's wall time (measurement included), s.
    """

    controller_set: ControllerSet
    fit: TwoMassFit
    speed_margins: Margins
    position_margins: Margins
    phase_margin_target: float
    position_limit: str
    source: str
    wall_s: float

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the set (a controller-set file's layout), margins, the fitted plant."""
        return {
            **self.controller_set.as_dict(),
            "margins": self.speed_margins.as_dict(),
            "position_margins": self.position_margins.as_dict(),
            "phase_margin_target_deg": self.phase_margin_target,
            "position_gain_limited_by": self.position_limit,
            "plant_fit": {
                **self.fit.parameters(),
                "resonance_hz": self.fit.plant.resonance_hz,
                **self.fit.drive_terms(),
                "not_identified": self.fit.not_identified(),
                "rms_db": self.fit.rms_db,
                "rms_deg": self.fit.rms_deg,
            },
            "frf": self.source,
            "wall_s": self.wall_s,
        }


def design_plant(fit: TwoMassFit, settings: ControllerSettings) -> TwoMass:
    """The design model: the fitted plant with the drive's torque constant and travel, its
    current lag, and its delay in whole speed-loop periods."""
    steps = max(0, round(fit.delay_s / settings.speed_period))
    return fit.plant.with_values(
        torque_constant=settings.torque_constant,
        travel_per_rad=settings.travel_per_rad,
        current_lag=fit.lag_s,
        dead_time=steps * settings.speed_period,
    )


def notch_candidates(plant: TwoMass) -> list[tuple[current_filters.CurrentFilter, ...]]:
    """The filter chains tried: none, and a notch on the first resonance of each width."""
    f_r = plant.resonance_hz
    j_total = plant.motor_inertia + plant.load_inertia
    rise = abs(plant.speed_per_torque(np.array([f_r]))[0]) * 2 * math.pi * f_r * j_total
    depth = float(np.clip(-20 * math.log10(rise), *NOTCH_DEPTH_DB))
    chains: list[tuple[current_filters.CurrentFilter, ...]] = [()]
    for width in NOTCH_WIDTHS:
        chains.append((Notch(float(f_r), width * float(f_r), depth),))
    return chains


def motor_alone(plant: TwoMass) -> TwoMass:
    """The motor without its load (backlash open): J_L and the coupling nearly nothing."""
    return plant.with_values(load_inertia=plant.load_inertia * 1e-9, stiffness=0.0, damping=0.0)


def _pi_response(kp: float, ki: float, f: np.ndarray, period: float) -> np.ndarray:
    """Kp + Ki z / (z - 1) at z = exp(j 2 pi f T)."""
    z = np.exp(2j * np.pi * f * period)
    return kp + ki * z / (z - 1.0)


def _speed_controller(
    kp: float,
    w_c: float,
    grid: np.ndarray,
    period: float,
    chain_response: np.ndarray,
    alpha: float,
) -> np.ndarray:
    """The PI of proportional gain ``kp`` (A/(rad/s)) and integral time alpha / w_c (s), then
    the filter chain, on the design grid."""
    return _pi_response(kp, kp * period * w_c / alpha, grid, period) * chain_response


def _acceptable(m: Margins, phase_margin: float) -> bool:
    return (
        m.phase_margin_deg is not None
        and m.phase_margin_deg >= phase_margin - TARGET_TOLERANCE_DEG
        and (m.gain_margin_db is None or m.gain_margin_db >= GAIN_MARGIN_DB)
        and m.peak_sensitivity_db <= PEAK_SENSITIVITY_DB
    )


def _phase_margin(grid: np.ndarray, loop: np.ndarray) -> float:
    """The phase margin (deg) of a loop on the design grid; -inf without a gain crossover."""
    margin = phase_margin_of(grid, loop)
    return -math.inf if margin is None else margin


def integral_factor(
    target: float, margin_of: Callable[[float], float]
) -> tuple[float | None, tuple[float, float]]:
    """The alpha (T_n = alpha / w_c) whose loop has the phase margin ``target`` (deg).

    ``margin_of(alpha)`` is the loop's phase margin; it grows with alpha (less integral, less
    phase lag at the crossover), so alpha is found by bisection in log(alpha) over
    :data:`INTEGRAL_FACTOR_RANGE`. Returns alpha (None when the target lies outside what the
    range reaches) and the phase margins at the ends of the range.
    """
    low, high = (math.log(a) for a in INTEGRAL_FACTOR_RANGE)
    ends = (margin_of(math.exp(low)), margin_of(math.exp(high)))
    if not ends[0] <= target <= ends[1]:
        return None, ends
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        if margin_of(math.exp(middle)) < target:
            low = middle
        else:
            high = middle
    return math.exp(high), ends


def speed_designs(
    plant: TwoMass, settings: ControllerSettings, phase_margin: float
) -> list[SpeedDesign]:
    """The speed-loop designs at the phase-margin target: for each filter chain and crossover
    of the grid, the integral time that gives the target (:func:`integral_factor`), kept when
    the loop keeps the other margins, coupled and decoupled.

    Raises
    ------
    ValueError
        When no design reaches the target and keeps the margins, with the phase margins the
        grid reaches.
    """
    period = settings.speed_period
    grid = dense_grid(LOW_HZ, 0.5 / period, DESIGN_POINTS)
    coupled = hold_discretised(plant, period, with_position=False).siso(grid)
    alone = hold_discretised(motor_alone(plant), period, with_position=False).siso(grid)
    j_total = plant.motor_inertia + plant.load_inertia
    designs = []
    reached = [math.inf, -math.inf]  # the lowest and highest phase margins the grid reaches
    for chain in notch_candidates(plant):
        chain_response = current_filters.chain_response(chain, grid, period)
        for f_c in np.geomspace(MIN_CROSSOVER_HZ, MAX_CROSSOVER * 0.5 / period, CROSSOVERS):
            w_c = 2 * math.pi * f_c
            kp = j_total * w_c / settings.torque_constant
            controller = functools.partial(_speed_controller, kp, w_c, grid, period, chain_response)
            alpha, ends = integral_factor(
                phase_margin,
                lambda a, controller=controller: _phase_margin(grid, controller(a) * coupled),
            )
            reached = [min(reached[0], ends[0]), max(reached[1], ends[1])]
            if alpha is None:
                continue
            margins = margins_of_data(grid, controller(alpha) * coupled)
            decoupled = margins_of_data(grid, controller(alpha) * alone)
            if _acceptable(margins, phase_margin) and _acceptable(decoupled, phase_margin):
                ki = kp * period * w_c / alpha
                designs.append(SpeedDesign(float(kp), float(ki), chain, margins))
    if not designs:
        raise ValueError(
            f"autotune: no speed-loop design reaches a phase margin of {phase_margin:g} deg "
            f"and keeps a gain margin of {GAIN_MARGIN_DB:g} dB and a peak sensitivity of "
            f"{PEAK_SENSITIVITY_DB:g} dB with the load coupled and with the motor alone; the "
            f"crossovers of {MIN_CROSSOVER_HZ:g}-{MAX_CROSSOVER * 0.5 / period:g} Hz reach "
            f"{reached[0]:.1f}-{reached[1]:.1f} deg on this plant"
        )
    return designs


def position_gain_limit(frequency_hz: np.ndarray, unit_loop: np.ndarray) -> float:
    """The highest Kp_pos (1/s) for which the position loop Kp_pos G keeps its margins (the
    smallest of :func:`position_gain_bounds`)."""
    return min(position_gain_bounds(frequency_hz, unit_loop).values())


def position_gain_bounds(frequency_hz: np.ndarray, unit_loop: np.ndarray) -> dict[str, float]:
    """The highest Kp_pos (1/s) each of the position loop's margins allows, by margin.

    ``unit_loop`` is G, the loop at Kp_pos = 1 (its phase does not depend on Kp_pos). Each
    condition bounds Kp_pos at every frequency:

    - gain margin: Kp |G| <= 10^(-GM/20) where G is real and negative (phase crossovers);
    - phase margin: Kp |G| < 1 wherever 180 deg + the phase of G is below the target (no gain
      crossover there);
    - closed-loop peak: |Kp G / (1 + Kp G)| <= M, i.e. Kp outside the roots of
      (M^2 - 1) |G|^2 Kp^2 + 2 M^2 Re(G) Kp + M^2 = 0.
    """
    g = unit_loop
    magnitude = np.abs(g)
    phase = np.degrees(np.unwrap(np.angle(g)))
    bounds = {}
    gains = [math.inf]
    turn = np.floor((phase + 180.0) / 360.0)
    for i in np.flatnonzero(np.diff(turn) != 0):
        level = -180.0 + 360.0 * max(turn[i], turn[i + 1])
        share = (level - phase[i]) / (phase[i + 1] - phase[i])
        at = magnitude[i] * (magnitude[i + 1] / magnitude[i]) ** share
        gains.append(10 ** (-POSITION_GAIN_MARGIN_DB / 20) / at)
    bounds[f"gain margin {POSITION_GAIN_MARGIN_DB:g} dB"] = min(gains)
    short = (np.mod(phase, 360.0) - 180.0) < POSITION_PHASE_MARGIN_DEG
    bounds[f"phase margin {POSITION_PHASE_MARGIN_DEG:g} deg"] = (
        1.0 / float(np.max(magnitude[short])) if short.any() else math.inf
    )
    m2 = 10 ** (POSITION_PEAK_DB / 10)
    a = (m2 - 1.0) * magnitude**2
    b = 2.0 * m2 * g.real
    root = b**2 - 4.0 * a * m2
    crossing = (root >= 0) & (g.real < 0)
    bounds[f"closed-loop peak {POSITION_PEAK_DB:g} dB"] = (
        float(np.min((-b[crossing] - np.sqrt(root[crossing])) / (2 * a[crossing])))
        if crossing.any()
        else math.inf
    )
    return bounds


def bandwidth_gain_limit(
    frequency_hz: np.ndarray, unit_loop: np.ndarray, highest: float, bandwidth_hz: float
) -> float:
    """The highest Kp_pos (1/s, at most ``highest``) whose closed position loop has a -3 dB
    bandwidth at most ``bandwidth_hz`` (Hz): the outer loop no faster than the inner one. The
    bandwidth grows with Kp_pos; found by bisection."""
    if (bandwidth_of(frequency_hz, highest * unit_loop) or math.inf) <= bandwidth_hz:
        return highest
    low, high = 0.0, highest
    for _ in range(BISECTIONS + 6):
        middle = 0.5 * (low + high)
        if (bandwidth_of(frequency_hz, middle * unit_loop) or math.inf) <= bandwidth_hz:
            low = middle
        else:
            high = middle
    return low


def position_gain(
    plant: TwoMass,
    speed: TunedParameters,
    settings: ControllerSettings,
    speed_bandwidth_hz: float | None,
) -> tuple[float, str]:
    """The highest Kp_pos (1/s) the position loop allows with the speed loop of ``speed``, and
    what limits it: a margin of :func:`position_gain_bounds`, or the speed loop's bandwidth
    ``speed_bandwidth_hz`` (Hz), which the position loop's may not exceed."""
    unit = LinearLoops(plant, speed_with(speed, Kp_pos=1.0), settings).position_open()
    grid = dense_grid(LOW_HZ, 0.5 / unit.dt, DESIGN_POINTS)
    loop = unit.siso(grid)
    bounds = position_gain_bounds(grid, loop)
    limit = min(bounds, key=bounds.get)
    gain = GRID_GUARD * bounds[limit]
    if speed_bandwidth_hz is not None and math.isfinite(gain):
        capped = bandwidth_gain_limit(grid, loop, gain, speed_bandwidth_hz)
        if capped < gain:
            gain, limit = capped, f"the speed loop's bandwidth {speed_bandwidth_hz:.3g} Hz"
    return gain, limit


def design_margins(system: Discrete) -> Margins:
    """A design loop's margins from its response on the design grid (the data method, which
    agrees with python-control's and spares importing it: tested)."""
    grid = dense_grid(LOW_HZ, 0.5 / system.dt, DESIGN_POINTS)
    return margins_of_data(grid, system.siso(grid))


def speed_with(tuned: TunedParameters, **changes: float) -> TunedParameters:
    """``tuned`` with some of its six parameters changed."""
    return TunedParameters(**{**tuned.as_dict(), **changes})


def autotune(
    frequency_hz: np.ndarray,
    response: np.ndarray,
    coherence: np.ndarray | None,
    scenario_tuned: TunedParameters,
    settings: ControllerSettings,
    source: str,
    phase_margin: float = PHASE_MARGIN_DEG,
    started: float | None = None,
) -> Autotuned:
    """Tune from a plant FRF (motor speed over torque setpoint, rad/s per N.m).

    Parameters
    ----------
    frequency_hz, response, coherence
        The FRF's lines to fit (Hz, complex, gamma^2 or None).
    scenario_tuned
        The scenario's set: its PP2, PP3 and f_H are kept.
    settings
        The scenario's controller settings (periods, torque constant, travel).
    source
        Where the FRF came from (reported).
    phase_margin
        The speed loop's phase-margin target, degrees.
    started
        ``time.perf_counter()`` when the tuning began (a measurement included); now when None.
    """
    started = time.perf_counter() if started is None else started
    fit = fit_two_mass(frequency_hz, response, coherence)
    plant = design_plant(fit, settings)
    inertia = plant.motor_inertia + plant.load_inertia
    best = None  # (Kp_pos, Ki_vel, crossover): the highest position gain, then stiffness
    for design in speed_designs(plant, settings, phase_margin):
        overrides = {
            "filters": design.filters,
            "ff_velocity": 1.0,
            "ff_acceleration": 1.0,
            "inertia": inertia,
        }
        design_settings = dataclasses.replace(settings, **overrides)
        gains = speed_with(scenario_tuned, Kp_vel=design.Kp_vel, Ki_vel=design.Ki_vel)
        kp_pos, limit = position_gain(plant, gains, design_settings, design.margins.bandwidth_hz)
        key = (round(kp_pos, 6), design.Ki_vel, design.margins.crossover_hz)
        if math.isfinite(kp_pos) and (best is None or key > best[0]):
            best = (key, speed_with(gains, Kp_pos=kp_pos), overrides, design_settings, limit)
    if best is None:
        raise ValueError("autotune: no position gain keeps the position loop's margins")
    _, tuned, overrides, design_settings, limit = best
    loops = LinearLoops(plant, tuned, design_settings)
    return Autotuned(
        controller_set=ControllerSet(tuned, overrides),
        fit=fit,
        speed_margins=design_margins(loops.speed_open()),
        position_margins=design_margins(loops.position_open()),
        phase_margin_target=phase_margin,
        position_limit=limit,
        source=source,
        wall_s=time.perf_counter() - started,
    )


def twin_plant_frf(plant: Plant, scenario: Scenario) -> FrequencyResponse:
    """The plant FRF measured on the twin as the tuner measures it (nonlinearities on, at
    ``twin bode``'s default operating point and excitation)."""
    settings = scenario.settings
    how = MeasurementSettings("plant")
    start = float(scenario.reference.position[0])
    measured = measure(plant, scenario.tuned, settings, scenario.plant_parameters, how, start)
    return measured.below(PLANT_BAND * 0.5 / settings.speed_period)


def propose(
    plant: Plant,
    scenario: Scenario,
    frf: Path | None = None,
    phase_margin: float = PHASE_MARGIN_DEG,
    coherence_floor: float = DEFAULT_COHERENCE_FLOOR,
) -> tuple[Autotuned, list[str]]:
    """The tuner's proposal for ``scenario`` from ``frf`` (or the twin's measured plant FRF on
    ``plant``), and the FRF file's masked bands in words."""
    started = time.perf_counter()
    if frf is None:
        measured = twin_plant_frf(plant, scenario)
        lines = (measured.frequency_hz, measured.response, measured.coherence)
        settings = scenario.settings
        source = (
            f"twin bode {scenario.name} --loop plant --speed "
            f"{MeasurementSettings('plant').operating_speed(settings):.4g} --amplitude "
            f"{default_amplitude('plant', scenario.tuned, settings):.4g} (the twin, measured)"
        )
        notes: list[str] = []
    else:
        data = read_frf(frf, coherence_floor)
        coherence = None if data.coherence is None else data.coherence[data.used]
        lines = (data.frequency_hz[data.used], data.response[data.used], coherence)
        source, notes = str(frf), data.notes(coherence_floor)
    proposal = autotune(
        *lines, scenario.tuned, scenario.settings, source, phase_margin, started=started
    )
    return proposal, notes


def autotune_scenario(
    scenario: Scenario,
    frf: Path | None,
    fmu: Path | None,
    phase_margin: float,
    coherence_floor: float,
) -> tuple[Autotuned, dict[str, Any]]:
    """Tune the scenario's controller from ``frf`` (or the twin's measured plant FRF).

    Returns
    -------
    tuple
        The proposal, and the metrics of a run of the scenario with it (``metrics``) and with
        the scenario's own set (``scenario_metrics``), plus the FRF's masked bands (``notes``)
        and the whole wall time (``wall_s``, s).
    """
    started = time.perf_counter()
    with Plant(scenario.plant_fmu(fmu)) as plant:
        proposal, notes = propose(plant, scenario, frf, phase_margin, coherence_floor)
        tuned_scenario = with_controller_set(scenario, proposal.controller_set)
        window = scenario.metrics_window
        metrics = compute_metrics(run_scenario(plant, tuned_scenario), window).as_dict()
        own = compute_metrics(run_scenario(plant, scenario), window).as_dict()
    return proposal, {
        "metrics": metrics,
        "scenario_metrics": own,
        "notes": notes,
        "wall_s": time.perf_counter() - started,
    }


def plot_design(proposal: Autotuned, scenario: Scenario, path: Path, command: str) -> Path:
    """The speed loop of the proposed set and of the scenario's own, on the fitted plant (the
    design model), the proposal's margins marked; ``command`` made it."""
    plant = design_plant(proposal.fit, scenario.settings)
    grid = dense_grid(LOW_HZ, 0.5 / scenario.settings.speed_period, DESIGN_POINTS)
    settings = proposal.controller_set.settings_for(scenario.settings)
    responses = {}
    for label, tuned, chosen in (
        ("twin autotune", proposal.controller_set.tuned, settings),
        ("the scenario's set", scenario.tuned, scenario.settings),
    ):
        loop = LinearLoops(plant, tuned, chosen).speed_open().siso(grid)
        responses[label] = FrequencyResponse("speed", "open", grid, loop)
    title = f"{scenario.name}: speed loop, open, on the fitted plant\n{command}"
    label = f"twin autotune (phase-margin target {proposal.phase_margin_target:g} deg): "
    return plot_bode(responses, title, path, proposal.speed_margins, margins_label=label)
