"""A frequency-response measurement on the twin, in closed loop, as a drive makes it.

The axis holds an operating point (standstill, or a constant carriage speed reached on a ramp
with the feedforwards on), the controller runs as in every run, and a multisine
(:mod:`twin_cosim.frequency.excitation`) is added at one point at that loop's sample rate:

- ``plant``: to the current (torque) command, after the speed controller; u is the current the
  plant receives, y the motor speed: P = G_dy / G_du (indirect method), over the torque constant
  the drive assumes, with the zero-order hold divided out;
- ``speed``: to the speed setpoint of the speed controller; e the speed error, y the motor
  speed: L_v = G_dy / G_de, T_v = G_dy / G_dr (r the setpoint with the excitation);
- ``position``: to the position setpoint of the position controller; e the position error,
  y the scale reading's deviation from the reference: L_x = G_dy / G_de, T_x = G_dy / G_dd.

Each realisation of the multisine runs two periods: the first lets the loop settle into its
periodic steady state, the second is recorded. Estimates: :mod:`twin_cosim.frequency.estimate`.
The compiled loop (:func:`twin_cosim.loops.kernels.measurement_loop`) calls the controller's own
functions (those of every run) and the FMU's fmi2 functions, as every run does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from twin_cosim import controller
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.cosim import fast_calls, raise_plant_error
from twin_cosim.frequency import estimate
from twin_cosim.frequency.excitation import Multisine, multisine
from twin_cosim.frequency.loops import hold_factor
from twin_cosim.frequency.response import FrequencyResponse, check_loop
from twin_cosim.loops import compiled_loops
from twin_cosim.plant import Plant

EXCITATION_SHARE = 0.05  # default excitation: a current of this share of the current limit (RMS)
SETTLE_S = 0.25  # s at the operating point before the first realisation
RAMP_ACCELERATION = 0.5  # m/s^2 up to the operating speed


@dataclass(frozen=True)
class MeasurementSettings:
    """How to measure.

    Attributes
    ----------
    loop : str
        plant, speed or position.
    kind : str
        open or closed.
    amplitude : float or None
        RMS of the excitation: A (plant), rad/s (speed) or m (position); None: the default,
        a current of 5 % of the current limit at high frequency (:func:`default_amplitude`).
    averages : int
        Multisine realisations averaged.
    speed : float
        Carriage speed of the operating point, m/s (0: standstill).
    low_hz : float
        Lowest excited frequency, Hz.
    speed_noise : float
        White noise on the measured motor speed, rad/s RMS (the controller sees it).
    seed : int
        Seed of the phases and the noise.
    """

    loop: str
    kind: str = "open"
    amplitude: float | None = None
    averages: int = 8
    speed: float = 0.0
    low_hz: float = 1.0
    speed_noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        check_loop(self.loop, self.kind)
        if self.amplitude is not None and not (
            math.isfinite(self.amplitude) and self.amplitude > 0
        ):
            raise ValueError(f"amplitude: expected a number > 0, got {self.amplitude}")
        if self.averages < 2:
            raise ValueError(f"averages: expected at least 2 realisations, got {self.averages}")
        if not (math.isfinite(self.low_hz) and self.low_hz > 0):
            raise ValueError(f"lowest frequency: expected a number > 0 Hz, got {self.low_hz}")
        if not (math.isfinite(self.speed_noise) and self.speed_noise >= 0):
            raise ValueError(f"speed noise: expected a number >= 0 rad/s, got {self.speed_noise}")
        if not math.isfinite(self.speed):
            raise ValueError(f"operating speed: expected a finite number, got {self.speed}")


def default_amplitude(loop: str, tuned: TunedParameters, settings: ControllerSettings) -> float:
    """The excitation's RMS that commands about 5 % of the current limit at high frequency.

    A (plant), rad/s (speed: over Kp_vel) or m (position: over Kp_pos / travel too).
    """
    current = EXCITATION_SHARE * settings.current_limit
    if loop == "plant":
        return current
    speed = current / tuned.Kp_vel
    return speed if loop == "speed" else speed * settings.travel_per_rad / tuned.Kp_pos


def block_samples(period: float) -> int:
    """Samples per multisine period at ``period`` (s): a power of two near 1 s."""
    return 2 ** max(4, round(math.log2(1.0 / period)))


@dataclass(frozen=True)
class _Layout:
    """Where the realisations lie in a run, in samples of the injection loop."""

    excitation: Multisine
    start: int  # first sample of the first realisation

    def recorded(self, m: int) -> slice:
        """The recorded (second) period of realisation m."""
        first = self.start + (2 * m + 1) * self.excitation.samples
        return slice(first, first + self.excitation.samples)


def _operating_point(
    speed: float, settings: ControllerSettings, lead_s: float, length_s: float, start: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference position (m), speed (m/s) and acceleration (m/s^2) per position sample: a
    ramp at :data:`RAMP_ACCELERATION` to ``speed``, then constant speed."""
    t = np.arange(math.ceil((lead_s + length_s) / settings.position_period) + 1)
    t = t * settings.position_period
    ramp = abs(speed) / RAMP_ACCELERATION
    a = math.copysign(RAMP_ACCELERATION, speed)
    t_ramp = np.minimum(t, ramp)
    x = start + 0.5 * a * t_ramp**2 + speed * (t - t_ramp)
    v = np.where(t < ramp, a * t, speed)
    return x, v, np.where(t < ramp, a, 0.0)


def measure(
    plant: Plant,
    tuned: TunedParameters,
    settings: ControllerSettings,
    plant_parameters: Mapping[str, float],
    how: MeasurementSettings,
    start_position: float = 0.0,
) -> FrequencyResponse:
    """Measure one frequency response on the twin.

    Parameters
    ----------
    plant
        The plant FMU.
    tuned, settings
        The controller (its current filters included).
    plant_parameters
        FMU parameter values (the nonlinearities switched off or not by the caller).
    how
        The loop, the excitation and the operating point.
    start_position
        Carriage position of the operating point at the start, m.

    Returns
    -------
    FrequencyResponse
        The estimate and its coherence at the excited lines.
    """
    at_speed_rate = how.loop in ("plant", "speed")
    period = settings.speed_period if at_speed_rate else settings.position_period
    ratio = settings.speed_steps_per_position_step
    samples = block_samples(period)
    rms = how.amplitude or default_amplitude(how.loop, tuned, settings)
    fold = samples // ratio if at_speed_rate and samples % ratio == 0 else samples
    excitation = multisine(samples, period, how.low_hz, rms, fold)
    lead_s = abs(how.speed) / RAMP_ACCELERATION + max(SETTLE_S, 20 * tuned.PP3)
    length_s = 2 * how.averages * samples * period
    x_ref, v_ref, a_ref = _operating_point(how.speed, settings, lead_s, length_s, start_position)
    n_position = len(x_ref)
    n_speed = n_position * ratio
    layout = _Layout(excitation, math.ceil(lead_s / period))
    rng = np.random.default_rng(how.seed)
    injected = np.zeros(n_speed if at_speed_rate else n_position)
    for m in range(how.averages):
        signal = excitation.realisation(rng)
        first = layout.start + 2 * m * samples
        injected[first : first + 2 * samples] = np.tile(signal, 2)
    zeros_speed, zeros_position = np.zeros(n_speed), np.zeros(n_position)
    noise = rng.normal(0.0, how.speed_noise, n_speed) if how.speed_noise else zeros_speed
    speeds = np.zeros((n_speed, 3))  # setpoint with injection, measured speed, current
    positions = np.zeros((n_position, 2))  # position error, deviation of the reading
    calls = fast_calls(plant)
    p = controller.parameter_vector(tuned, settings)
    s = controller.initial_state(len(settings.filters))
    plant.start_run(plant_parameters)
    status, step = compiled_loops().measurement_loop(
        calls.set_real,
        calls.do_step,
        calls.get_real,
        plant.fmu.component,
        calls.vr_in,
        calls.vr_out,
        p,
        s,
        settings.position_period,
        ratio,
        x_ref,
        v_ref,
        a_ref,
        injected if how.loop == "plant" else zeros_speed,
        injected if how.loop == "speed" else zeros_speed,
        injected if how.loop == "position" else zeros_position,
        noise,
        speeds,
        positions,
    )
    if status != 0:
        raise_plant_error(plant, status, step, settings.speed_period)
    return _estimate(how, layout, injected, speeds, positions, settings)


def _estimate(
    how: MeasurementSettings,
    layout: _Layout,
    injected: np.ndarray,
    speeds: np.ndarray,
    positions: np.ndarray,
    settings: ControllerSettings,
) -> FrequencyResponse:
    """The response at the excited lines from the recorded periods."""
    bins = layout.excitation.bins

    def spectra(signal: np.ndarray) -> np.ndarray:
        periods = np.stack([signal[layout.recorded(m)] for m in range(how.averages)])
        return estimate.line_spectra(periods, bins)

    d = spectra(injected)
    f = layout.excitation.frequency_hz
    if how.loop == "plant":
        value, gamma = estimate.ratio(d, spectra(speeds[:, 1]), spectra(speeds[:, 2]))
        value = value / settings.torque_constant / hold_factor(f, settings.speed_period)
    elif how.loop == "speed":
        y = spectra(speeds[:, 1])
        u = spectra(speeds[:, 0] - speeds[:, 1]) if how.kind == "open" else spectra(speeds[:, 0])
        value, gamma = estimate.ratio(d, y, u)
    else:
        y = spectra(positions[:, 1])
        u = spectra(positions[:, 0]) if how.kind == "open" else d
        value, gamma = estimate.ratio(d, y, u)
    return FrequencyResponse(how.loop, how.kind, f, value, gamma)
