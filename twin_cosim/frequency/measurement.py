"""A frequency response measured on the twin, in closed loop, as a drive measures it: the
multisine excitation, the measurement, the H1 estimate and the response it gives.

The loops a drive measures and what each response is:

- ``plant``: the mechanics as the drive sees them, motor speed over the torque setpoint
  (rad/s per N.m, eq. (3)), measured open through the closed loops (indirect method); the
  zero-order hold of the drive's sample period is taken out, so that it compares with the
  continuous eq. (3), up to :data:`PLANT_BAND` of the Nyquist frequency (1 kHz at 62.5 us),
  below which what the hold aliases stays under 0.1 dB;
- ``speed``: the speed loop, open L_v (speed error -> motor speed) or closed T_v (speed
  setpoint -> motor speed), 1;
- ``position``: the position loop, open L_x (position error -> scale reading) or closed T_x
  (position setpoint -> scale reading), 1.

The measurement: the axis holds an operating point (standstill, or a constant carriage speed
reached on a ramp with the feedforwards on), the controller runs as in every run, and a
multisine is added at one point at that loop's sample rate:

- ``plant``: to the current (torque) command, after the speed controller; u is the current the
  plant receives, y the motor speed: P = G_dy / G_du (indirect method), over the torque constant
  the drive assumes, with the zero-order hold divided out;
- ``speed``: to the speed setpoint of the speed controller; e the speed error, y the motor
  speed: L_v = G_dy / G_de, T_v = G_dy / G_dr (r the setpoint with the excitation);
- ``position``: to the position setpoint of the position controller; e the position error,
  y the scale reading's deviation from the reference: L_x = G_dy / G_de, T_x = G_dy / G_dd.

Each realisation of the multisine runs two periods: the first lets the loop settle into its
periodic steady state, the second is recorded. The measurement is a run of the master
(:func:`twin_cosim.cosim.run_axes`, compiled) with the excitation injected at its loop, the
noise on the measured speed, and the speed-loop record: the controller's own functions (those of
every run) and the FMU's FMI functions, as every run.

The multisine: a period of N samples at the period T excites the lines k / (N T) Hz of a set of
bins k, so that a whole period in the window leaks nothing. The bins are log-spaced from the
lowest frequency up to the Nyquist frequency (bin N / 2, excited with a random sign), at most
``lines_per_decade`` per decade and never twice the same. A loop that injects at the speed-loop
rate while the position loop samples every R speed samples folds each line f onto the images
m / (R T) +- f. Two excited lines whose bins agree modulo N / R, or add up to a multiple of it,
would respond to each other; the bins are chosen so that none do (``fold``), and a linear twin
then gives coherence 1 at every line. Each realisation draws new phases (uniform), so that
averaging over realisations turns the response to what is not linear into noise, which the
coherence shows.

The estimate: with the excitation d, a measured output y and, for the indirect (closed-loop)
method, the signal u at the input of what is measured, each recorded over one steady-state
period per realisation m, at an excited line::

    G_dy = sum_m Y_m conj(D_m),   G_dd = sum_m |D_m|^2,   G_yy = sum_m |Y_m|^2
    H1   = G_dy / G_dd                          (y over d)
    H    = G_dy / G_du                          (y over u, indirect: both from the same d)
    gamma^2 = |G_dy|^2 / (G_dd G_yy)            (coherence of y with d)

The indirect estimate measures what lies between u and y without the bias feedback gives a
direct estimate: d is the only signal both share. Its coherence is the smaller of those of y
and of u with d. In a linear, noise-free loop at steady state it is 1; noise, and the
response to what is not linear (which changes with every realisation), lower it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.cosim import AxisRecord, AxisRun, Injections, run_axes
from twin_cosim.frequency.linear import hold_factor
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid

LOOPS = ("plant", "speed", "position")
PLANT_BAND = 1 / 8  # of the Nyquist frequency: the continuous plant response is given below
UNITS = {"plant": "rad/s per N.m", "speed": "1", "position": "1"}
DESCRIPTIONS = {
    ("plant", "open"): "motor speed over torque setpoint (eq. (3))",
    ("speed", "open"): "speed loop, open: speed error -> motor speed",
    ("speed", "closed"): "speed loop, closed: speed setpoint -> motor speed",
    ("position", "open"): "position loop, open: position error -> scale reading",
    ("position", "closed"): "position loop, closed: position setpoint -> scale reading",
}
LINES_PER_DECADE = 100
EXCITATION_SHARE = 0.05  # default excitation: a current of this share of the current limit (RMS)
SETTLE_S = 0.25  # s at the operating point before the first realisation
RAMP_ACCELERATION = 0.5  # m/s^2 up to the operating speed


def check_loop(loop: str, kind: str) -> None:
    """ValueError unless (loop, kind) is a response a drive measures."""
    if loop not in LOOPS:
        raise ValueError(f"loop {loop!r}: expected one of {list(LOOPS)}")
    if (loop, kind) not in DESCRIPTIONS:
        raise ValueError(
            f"--loop {loop} --{kind}: the plant is measured open (the mechanics, through the "
            "closed loops); --closed applies to the speed and position loops"
        )


@dataclass(frozen=True)
class FrequencyResponse:
    """Complex response values at increasing frequencies.

    Attributes
    ----------
    loop : str
        plant, speed or position (:data:`LOOPS`).
    kind : str
        open or closed.
    frequency_hz : numpy.ndarray
        Frequencies, Hz.
    response : numpy.ndarray
        Complex values, unit :data:`UNITS` of the loop.
    coherence : numpy.ndarray or None
        gamma^2 per frequency (None for a computed response).
    """

    loop: str
    kind: str
    frequency_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray | None = None

    def below(self, frequency_hz: float) -> FrequencyResponse:
        """The response at the lines up to ``frequency_hz`` (Hz)."""
        keep = self.frequency_hz <= frequency_hz
        return FrequencyResponse(
            self.loop,
            self.kind,
            self.frequency_hz[keep],
            self.response[keep],
            None if self.coherence is None else self.coherence[keep],
        )

    @property
    def magnitude_db(self) -> np.ndarray:
        """20 log10 |H|, dB (re 1 of the loop's unit)."""
        return 20 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """The phase, degrees in (-180, 180]."""
        return np.degrees(np.angle(self.response))

    @property
    def unit(self) -> str:
        """The unit of the response values."""
        return UNITS[self.loop]

    @property
    def description(self) -> str:
        """What the response is, in words."""
        return DESCRIPTIONS[(self.loop, self.kind)]


@dataclass(frozen=True)
class Multisine:
    """The lines and amplitude of a multisine.

    Attributes
    ----------
    samples : int
        Samples per period N.
    period : float
        Sample period T, s.
    bins : numpy.ndarray
        Excited DFT bins k (frequencies k / (N T)), increasing.
    amplitude : float
        Amplitude of every line, in the unit of the injected signal.
    """

    samples: int
    period: float
    bins: np.ndarray
    amplitude: float

    @property
    def frequency_hz(self) -> np.ndarray:
        """The excited frequencies, Hz."""
        return self.bins / (self.samples * self.period)

    def realisation(self, rng: np.random.Generator) -> np.ndarray:
        """One period with random phases (uniform; a random sign at the Nyquist bin)."""
        spectrum = np.zeros(self.samples // 2 + 1, dtype=np.complex128)
        phases = rng.uniform(0.0, 2 * math.pi, len(self.bins))
        # irfft: a bin k < N/2 of value N/2 exp(j phi) is cos(2 pi k n / N + phi); bin N/2 of
        # value N is (-1)^n
        spectrum[self.bins] = self.samples / 2 * np.exp(1j * phases)
        if self.bins[-1] == self.samples // 2:
            spectrum[-1] = self.samples * (1.0 if math.cos(phases[-1]) >= 0 else -1.0)
        return self.amplitude * np.fft.irfft(spectrum, self.samples)


def choose_bins(
    samples: int, low_bin: int, fold: int, lines_per_decade: int = LINES_PER_DECADE
) -> np.ndarray:
    """Log-spaced bins from ``low_bin`` to the Nyquist bin, none the image of another.

    ``fold`` is the period of the images in bins (N / R, or N when nothing folds): no two bins
    agree modulo it, nor add up to a multiple of it.
    """
    nyquist = samples // 2
    count = round(lines_per_decade * math.log10(nyquist / low_bin)) + 1
    targets = np.unique(np.round(np.geomspace(low_bin, nyquist, max(count, 2))).astype(int))
    residues: set[int] = set()
    chosen = []
    for target in targets:
        reach = max(1, int(0.01 * target))  # look this far either side of the target
        for k in sorted(range(target - reach, target + reach + 1), key=lambda b: abs(b - target)):
            own = {k % fold, -k % fold}
            if low_bin <= k <= nyquist and k not in chosen and not own & residues:
                residues |= own
                chosen.append(k)
                break
    return np.array(sorted(chosen))


def multisine(
    samples: int,
    period: float,
    low_hz: float,
    rms: float,
    fold: int,
    lines_per_decade: int = LINES_PER_DECADE,
) -> Multisine:
    """A multisine of ``samples`` per period at ``period`` (s) from ``low_hz`` (Hz) up.

    ``rms`` is the RMS value of the whole signal (unit of the injected signal); ``fold`` as
    :func:`choose_bins`.
    """
    low_bin = max(1, math.ceil(low_hz * samples * period - 1e-9))
    bins = choose_bins(samples, low_bin, fold, lines_per_decade)
    nyquist = int(bins[-1] == samples // 2)  # a line of mean square a^2, the others a^2 / 2
    return Multisine(samples, period, bins, rms / math.sqrt((len(bins) - nyquist) / 2 + nyquist))


def line_spectra(periods: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """DFT of each recorded period at the excited bins, shape (realisations, lines)."""
    return np.fft.rfft(periods, axis=-1)[:, bins]


def coherence(d: np.ndarray, y: np.ndarray) -> np.ndarray:
    """gamma^2 of y with d at each line, from line spectra (realisations, lines)."""
    cross = np.abs(np.sum(y * np.conj(d), axis=0)) ** 2
    power = np.sum(np.abs(d) ** 2, axis=0) * np.sum(np.abs(y) ** 2, axis=0)
    return np.divide(cross, power, out=np.zeros_like(cross), where=power > 0)


def indirect_ratio(d: np.ndarray, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """y over u estimated through d (H1 of each over d), and its coherence, per line.

    Parameters
    ----------
    d, y, u
        Line spectra (realisations, lines) of the excitation, the output and the input.

    Returns
    -------
    tuple
        The complex estimate and the coherence (the smaller of y's and u's with d).
    """
    estimate = np.sum(y * np.conj(d), axis=0) / np.sum(u * np.conj(d), axis=0)
    return estimate, np.minimum(coherence(d, y), coherence(d, u))


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
    at = {"plant": "current", "speed": "speed", "position": "position"}[how.loop]
    noise = rng.normal(0.0, how.speed_noise, n_speed) if how.speed_noise else None
    axis = AxisRun(
        "",
        plant,
        ReferenceGrid(settings.position_period, x_ref, v_ref, a_ref),
        tuned,
        settings,
        plant_parameters,
        Injections(speed_noise=noise, **{at: injected}),
    )
    recorded = run_axes([axis], speed_loop_record=True)[axis.name]
    return _estimate(how, layout, injected, recorded, settings)


def _estimate(
    how: MeasurementSettings,
    layout: _Layout,
    injected: np.ndarray,
    recorded: AxisRecord,
    settings: ControllerSettings,
) -> FrequencyResponse:
    """The response at the excited lines from the recorded periods (of the speed-loop record,
    or the position-loop record for the position loop)."""
    bins = layout.excitation.bins

    def spectra(signal: np.ndarray) -> np.ndarray:
        periods = np.stack([signal[layout.recorded(m)] for m in range(how.averages)])
        return line_spectra(periods, bins)

    d = spectra(injected)
    f = layout.excitation.frequency_hz
    speeds, positions = recorded.speed_loop, recorded.position_loop
    if how.loop == "plant":
        value, gamma = indirect_ratio(d, spectra(speeds["speed"]), spectra(speeds["current"]))
        value = value / settings.torque_constant / hold_factor(f, settings.speed_period)
    elif how.loop == "speed":
        setpoint = speeds["speed_setpoint"]
        y = spectra(speeds["speed"])
        u = spectra(setpoint - speeds["speed"]) if how.kind == "open" else spectra(setpoint)
        value, gamma = indirect_ratio(d, y, u)
    else:  # e: the position setpoint - x; y: the reading's deviation from the reference
        y = spectra(positions["x"] - positions["x_ref"])
        u = spectra(positions["error"]) if how.kind == "open" else d
        value, gamma = indirect_ratio(d, y, u)
    return FrequencyResponse(how.loop, how.kind, f, value, gamma)
