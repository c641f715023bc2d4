"""The noise stage: the measured noise as plant parameters, the noise floors, and what noise
alone does to the figures of merit (so that noise is never called a gap).

**Noise harmonics.** The plant adds x_noise(t) = sum_k A_k sin(2 pi f_k t + phi_k) (k = 1..4) to
the measured position, t the absolute simulation time in s. :func:`noise_harmonics` identifies
these harmonics from a measured run:

1. Standstill stretches: runs of ``mask`` contiguous in index and on the regular time grid (a
   jump in time, as between concatenated runs, ends a stretch) lasting at least 0.2 s; each
   stretch's mean is removed.
2. Detection: the Hann amplitude spectra of the stretches are averaged (see
   :mod:`twin_cosim.gap.spectra`); a harmonic must stand ``min_ratio`` times above the
   median of that spectrum and make at least two cycles in the longest stretch. Harmonics are
   taken one at a time, largest first, each from the spectrum of what the harmonics found so far
   leave unexplained, so that the side lobes of a large harmonic are not taken for harmonics.
3. Refinement: after each detection, the frequencies of all harmonics found are fitted by
   nonlinear least squares (``scipy.optimize.least_squares``), first on the longest stretch (one
   minimum near the spectral estimate), then on all stretches together in absolute time; for
   given frequencies, amplitudes, phases and one offset per stretch are linear and solved
   exactly (variable projection). The phases are thereby referenced to t = 0. Between stretches
   the harmonics are assumed to run on with a constant phase, as in the plant model; stretches
   far apart in time leave a comb of nearly equal fits 1 / (spacing) apart in frequency, and the
   fit on the longest stretch picks the tooth.

The harmonics become plant parameters (:func:`identify_noise`) only when every value lies in the
FMU's variable ranges and the frequency below the Nyquist frequency of the run, and when the
held-out data confirm them (:func:`confirmed_harmonics`): at the held-out standstill stretches,
the harmonic as identified (amplitude, frequency and phase in absolute time) must leave less of
the residual than it finds there, beyond what chance makes of the drop when all that the
harmonic leaves there counts as noise (evidence z at the diagnosis' significance level). A
harmonic of the machine's noise runs on in phase and passes; what an unmodelled effect leaves at
standstill in the training data (the settling of a dead time, the creep of a Stribeck curve:
0.03-1.2 um at 0.5-12 Hz on random virtual machines whose noise is white) does not repeat in
phase, and a twin that replayed it would carry a sinusoid its machine does not have. Held-out
runs of their own start their clocks at 0, as the plant does: a harmonic passes there when its
phase is tied to each run's start; one whose phase wanders from run to run (mains hum) is
dropped, because the twin cannot replay it in phase and out of phase it adds its energy. A
harmonic that cannot be identified or confirmed is dropped and reported, never written to the
FMU.

**Noise floors** sigma_x (m), sigma_i (A; rad/s for the motor speed of an open-loop run)
normalise every residual (:func:`noise_floors`). A floor must come from what no effect of the
library explains:

- from **repeats** when the training data hold them (runs with the same input: the same
  reference and disturbance, or the same drive signal of an open-loop run;
  :func:`repeat_floor`): the robust spread (1.4826 MAD) of each run's residual around the mean of
  its repeats, sample by sample, times sqrt(k / (k - 1)) for k repeats. The twin replays each
  repeat alike, so this is the machine's real repeatability, its drift between runs included;
- otherwise from the **high-frequency part** of the residual (:func:`high_frequency_sigma`): the
  robust spread of its second difference divided by sqrt(6) (white noise of spread s gives
  second differences of spread sqrt(6) s, a smooth model error almost none). The library's
  effects are smooth at the sample rate: on runs of each effect alone (``twin synth`` on
  ``scenarios/diagnosis.yaml``, moderate sizes) this floor lies within 4 % of the true noise,
  where the residual at standstill (the floor before) took up a Stribeck curve's sticking (5.2
  times the current noise), torque ripple (1.6) and lead error (1.5).

Neither falls below the encoder's quantisation noise q / sqrt(12) when the position lies on a
grid of step q. The source of each floor is reported.

**Noise and the figures of merit** (:func:`compare_metrics`): the measured E_pk, ITAE and IAU are
compared with the twin's, computed on the replay plus ``noise_draws`` seeded draws of white noise
at the floors (noise makes |e| and |i| larger on average, which alone moves ITAE and IAU by a few
percent); a metric is off when its relative error exceeds ``significance_metric`` plus
``significance_noise`` standard deviations of its noise-only spread.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from twin_cosim.gap.data import regimes as regime_model
from twin_cosim.gap.data.residuals import Residuals, run_metrics, sim_at
from twin_cosim.gap.floors.evidence import (
    EFFECTIVE_SAMPLE_SPACING_S,
    correlation_time,
    critical_z,
    improvement_z,
)
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.spectra import dominant_peak, mean_amplitude_spectrum
from twin_cosim.measured import MeasuredRun
from twin_cosim.run_record import RunRecord

MIN_STRETCH = 0.2  # s, shortest standstill stretch used for the harmonics
MIN_CYCLES = 2.0  # least cycles of a harmonic in the longest stretch
MAD_TO_SIGMA = 1.4826  # standard deviation / MAD of a normal distribution
SECOND_DIFFERENCE_GAIN = math.sqrt(6.0)  # spread of x[k+1] - 2 x[k] + x[k-1] for white x
QUANTISATION_GAIN = 1.0 / math.sqrt(12.0)  # spread of the rounding error of a grid of step 1
MIN_SIGMA_POSITION = 1e-12  # m, guards a perfect replay of noise-free data
MIN_SIGMA_CURRENT = 1e-9  # A


@dataclass(frozen=True)
class Harmonic:
    """One sinusoid A sin(2 pi f t + phi) of the noise, t the absolute time.

    Attributes
    ----------
    amplitude_m : float
        Amplitude A, m.
    frequency_hz : float
        Frequency f, Hz.
    phase_rad : float
        Phase phi at t = 0, rad, in [-pi, pi).
    """

    amplitude_m: float
    frequency_hz: float
    phase_rad: float


def _wrap(phase: float) -> float:
    """Phase wrapped to [-pi, pi), rad."""
    return float((phase + np.pi) % (2.0 * np.pi) - np.pi)


def _design(frequencies: np.ndarray, times: Sequence[np.ndarray]) -> np.ndarray:
    """Columns sin and cos of each frequency (Hz) at all times (s), then one offset per stretch."""
    t = np.concatenate(times)
    phase = 2.0 * np.pi * np.outer(t, frequencies)
    offsets = np.zeros((t.size, len(times)))
    first = np.cumsum([0] + [len(s) for s in times])
    for k, (a, b) in enumerate(zip(first[:-1], first[1:], strict=True)):
        offsets[a:b, k] = 1.0
    return np.hstack((np.sin(phase), np.cos(phase), offsets))


def _fit_frequencies(
    frequencies: np.ndarray, times: Sequence[np.ndarray], values: Sequence[np.ndarray]
) -> np.ndarray:
    """Frequencies (Hz) that fit the stretches best, the linear coefficients projected out."""
    x = np.concatenate(values)
    scale = float(np.std(x)) or 1.0

    def misfit(f: np.ndarray) -> np.ndarray:
        design = _design(f, times)
        coefficients = np.linalg.lstsq(design, x / scale, rcond=None)[0]
        return x / scale - design @ coefficients

    return least_squares(misfit, frequencies, x_scale="jac").x


def _linear_fit(
    frequencies: np.ndarray, times: Sequence[np.ndarray], values: Sequence[np.ndarray]
) -> np.ndarray:
    """Coefficients (sin, cos per frequency, then the offsets per stretch), m."""
    return np.linalg.lstsq(_design(frequencies, times), np.concatenate(values), rcond=None)[0]


def _leftovers(
    frequencies: np.ndarray, times: Sequence[np.ndarray], values: Sequence[np.ndarray]
) -> list[np.ndarray]:
    """What the harmonics at ``frequencies`` (Hz) leave of each stretch, mean removed, m."""
    if frequencies.size == 0:
        return list(values)
    fitted = _design(frequencies, times) @ _linear_fit(frequencies, times, values)
    left = np.concatenate(values) - fitted
    pieces = np.split(left, np.cumsum([len(v) for v in values])[:-1])
    return [p - p.mean() for p in pieces]


def _stretches(t: np.ndarray, mask: np.ndarray, dt: float) -> list[tuple[int, int]]:
    """Standstill stretches lasting at least :data:`MIN_STRETCH`, longest first.

    A stretch is contiguous in index and in time: it ends where the time step departs from
    ``dt`` (s) by more than half, as between runs concatenated into one record.
    """
    regular = np.abs(np.diff(t) - dt) <= 0.5 * dt
    breaks = np.flatnonzero(~regular) + 1
    runs = []
    for start, stop in regime_model.segments(mask, 1):
        inner = breaks[(breaks > start) & (breaks < stop)]
        edges = [start, *inner.tolist(), stop]
        runs += [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    long = [s for s in runs if (s[1] - s[0]) * dt >= MIN_STRETCH - 1e-9]
    return sorted(long, key=lambda s: s[0] - s[1])


def noise_harmonics(
    t: np.ndarray, x: np.ndarray, mask: np.ndarray, count: int = 4, min_ratio: float = 5.0
) -> list[Harmonic]:
    """Main harmonics of the measured position noise at standstill (see the module docstring).

    Parameters
    ----------
    t : np.ndarray
        Absolute sample times, s, on a regular grid (runs concatenated: may jump between runs).
    x : np.ndarray
        Measured position, m.
    mask : np.ndarray
        True at the standstill samples.
    count : int
        Most harmonics returned.
    min_ratio : float
        Least ratio of a harmonic's spectral peak to the median spectrum amplitude.

    Returns
    -------
    list[Harmonic]
        Up to ``count`` harmonics such that x_noise(t) ~ sum A sin(2 pi f t + phi), largest
        amplitude first; empty without a standstill stretch of 0.2 s or a significant peak.

    Raises
    ------
    ValueError
        When the arrays are not 1-D of one length, or x is not finite at standstill.
    """
    t, x, mask = np.asarray(t, dtype=float), np.asarray(x, dtype=float), np.asarray(mask, bool)
    if t.ndim != 1 or x.shape != t.shape or mask.shape != t.shape or t.size < 2:
        raise ValueError("t, x and mask must be 1-D arrays of one length, at least 2 samples")
    if not np.all(np.isfinite(x[mask])):
        raise ValueError("the position holds non-finite values at standstill")
    dt = float(np.median(np.diff(t)))
    stretches = _stretches(t, mask, dt)
    if not stretches:
        return []
    times = [t[a:b] for a, b in stretches]
    values = [x[a:b] - x[a:b].mean() for a, b in stretches]
    frequency, spectrum = mean_amplitude_spectrum(values, dt, [len(v) for v in values])
    threshold = min_ratio * float(np.median(spectrum[1:]))
    searched = frequency >= MIN_CYCLES / (len(values[0]) * dt)
    found = np.empty(0)
    while found.size < count:
        _, left = mean_amplitude_spectrum(
            _leftovers(found, times, values), dt, [len(v) for v in values]
        )
        peak = dominant_peak(frequency[searched], left[searched], min_ratio=0.0)
        if peak is None or peak.amplitude < threshold:
            break
        found = _fit_frequencies(np.append(found, peak.location), times[:1], values[:1])
        found = _fit_frequencies(found, times, values)
    return _harmonics(found, times, values)


def _harmonics(
    frequencies: np.ndarray, times: Sequence[np.ndarray], values: Sequence[np.ndarray]
) -> list[Harmonic]:
    """Amplitudes and phases at given frequencies (Hz), largest amplitude first."""
    if frequencies.size == 0:
        return []
    coefficients = _linear_fit(frequencies, times, values)
    sine, cosine = np.split(coefficients[: 2 * frequencies.size], 2)
    harmonics = [
        Harmonic(float(np.hypot(a, b)), float(f), _wrap(np.arctan2(b, a)))
        for a, b, f in zip(sine, cosine, frequencies, strict=True)
    ]
    return sorted(harmonics, key=lambda h: -h.amplitude_m)


def plant_slots(start_values: Mapping[str, float]) -> int:
    """Number of noise harmonics a plant model holds: its parameters noise_amplitude_1, 2, ..."""
    count = 0
    while f"noise_amplitude_{count + 1}" in start_values:
        count += 1
    return count


def as_plant_parameters(
    harmonics: Sequence[Harmonic], start_values: Mapping[str, float]
) -> dict[str, float]:
    """Noise parameters of the plant FMU for its harmonic slots (:func:`plant_slots`).

    Keys noise_amplitude_k (m), noise_frequency_k (Hz) and noise_phase_k (rad, wrapped to
    [-pi, pi)), in the order given. Unused slots get amplitude 0 and keep the frequency and
    phase of ``start_values`` (the FMU's start values).

    Raises
    ------
    ValueError
        When there are more harmonics than slots.
    """
    slots = plant_slots(start_values)
    if len(harmonics) > slots:
        raise ValueError(f"the plant holds {slots} noise harmonics, got {len(harmonics)}")
    parameters = {}
    for k in range(1, slots + 1):
        if k <= len(harmonics):
            h = harmonics[k - 1]
            amplitude, frequency, phase = h.amplitude_m, h.frequency_hz, _wrap(h.phase_rad)
        else:
            amplitude = 0.0
            frequency = start_values[f"noise_frequency_{k}"]
            phase = start_values[f"noise_phase_{k}"]
        parameters[f"noise_amplitude_{k}"] = amplitude
        parameters[f"noise_frequency_{k}"] = frequency
        parameters[f"noise_phase_{k}"] = phase
    return parameters


@dataclass(frozen=True)
class NoiseModel:
    """Noise harmonics accepted as plant parameters, and those dropped with the reason."""

    harmonics: list[Harmonic]
    plant_parameters: dict[str, float]
    dropped: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Floors:
    """Noise floors of the residuals and where each came from."""

    sigma_position_m: float
    sigma_current: float
    position_source: str
    current_source: str


def identify_noise(
    raw: Residuals,
    held: Residuals,
    dt: float,
    ranges: dict[str, tuple[float, float]],
    start_values: dict[str, float],
    level: float,
) -> NoiseModel:
    """Noise harmonics of the measured position at standstill, checked against the FMU's ranges
    and confirmed on the held-out data (:func:`confirmed_harmonics`).

    Parameters
    ----------
    raw : Residuals
        Training residual against the replay without noise model (its position is measured
        minus noise-free simulated, so at standstill it is the measured noise and what the
        twin's effects leave there).
    held : Residuals
        Held-out residual against the replay without noise model.
    dt : float
        Sample period, s.
    ranges : dict
        (min, max) of the FMU parameters by name.
    start_values : dict
        The FMU's parameter values (the number of harmonic slots and their defaults).
    level : float
        Significance level of the harmonics' confirmations together (one-sided).
    """
    slots = plant_slots(start_values)
    if slots == 0:
        return NoiseModel([], {}, [])  # the plant model has no noise harmonics to set
    still = raw.regimes == regime_model.STANDSTILL
    try:
        found = noise_harmonics(raw.t, raw.position, still, count=slots)
    except ValueError as exc:
        return NoiseModel([], {}, [f"noise harmonics not identified: {exc}"])
    kept, dropped = _settable(found[:slots], dt, ranges, start_values)
    kept, unconfirmed = confirmed_harmonics(kept, held, dt, level)
    kept, unset = _settable(kept, dt, ranges, start_values)  # in the slots they now take
    parameters = as_plant_parameters(kept, start_values) if kept else {}
    return NoiseModel(kept, parameters, dropped + unconfirmed + unset)


def _settable(
    harmonics: Sequence[Harmonic],
    dt: float,
    ranges: dict[str, tuple[float, float]],
    start_values: dict[str, float],
) -> tuple[list[Harmonic], list[str]]:
    """The harmonics, in order, whose values fit the FMU's variable ranges in the slots they
    take and whose frequency lies below the Nyquist frequency of the sample period ``dt`` (s);
    and why each other one is dropped."""
    nyquist = 0.5 / dt
    kept, dropped = [], []
    for harmonic in harmonics:
        slot = as_plant_parameters([*kept, harmonic], start_values)
        problem = _out_of_range(slot, ranges)
        if not 0.0 < harmonic.frequency_hz < nyquist:
            problem = f"frequency {harmonic.frequency_hz:.4g} Hz outside (0, {nyquist:.4g}) Hz"
        if problem:
            dropped.append(f"{_named(harmonic)} dropped: {problem}")
        else:
            kept.append(harmonic)
    return kept, dropped


def confirmed_harmonics(
    harmonics: Sequence[Harmonic], held: Residuals, dt: float, level: float
) -> tuple[list[Harmonic], list[str]]:
    """The harmonics the held-out standstill confirms, and why each other one is dropped.

    Largest first, each harmonic is predicted at the held-out standstill stretches (as
    :func:`noise_harmonics` takes them, each stretch's mean removed) from its amplitude,
    frequency and phase alone. It is confirmed when subtracting it leaves less energy in the
    position residual there, beyond what chance makes of it: the drop's evidence z
    (:func:`~twin_cosim.gap.floors.evidence.improvement_z`, everything the harmonic leaves
    counted as noise, one independent sample per its correlation time and at least per 10 ms)
    at least the one-sided quantile of ``level`` shared by the harmonics judged. The next
    harmonic is judged on what the confirmed ones leave. Without a held-out standstill stretch
    of :data:`MIN_STRETCH` none is confirmed.

    Counting what is left as noise, with its own correlation, matters where the standstill
    holds more than noise: on a virtual machine with backlash, a current lag and a Stribeck
    curve (white noise of 20 nm), the held-out standstill residual was 4.7 um RMS, correlated
    over 54-86 ms, and a 0.94 um sinusoid at 4.3 Hz (26 cycles of the excitation's 6 s
    pattern, so in phase with what repeats) went into the plant, confirmed by an energy drop
    alone; its least-squares multiple was -0.49 in one held-out stretch and 5.9 in the other.
    Its evidence is z 2.7 with one sample per 10 ms (2.8 needed), z 1.0 with its correlation
    time.

    Parameters
    ----------
    harmonics : sequence of Harmonic
        Identified on the training data, largest first.
    held : Residuals
        Held-out residual against the replay without noise model.
    dt : float
        Sample period, s.
    level : float
        Significance level of the confirmations together (one-sided).

    Returns
    -------
    tuple of (list of Harmonic, list of str)
        The confirmed harmonics (in the order given) and one reason per dropped harmonic.
    """
    stretches = _stretches(held.t, held.regimes == regime_model.STANDSTILL, dt)
    times = [held.t[a:b] for a, b in stretches]
    duration = sum(float(t[-1] - t[0]) for t in times)
    needed = critical_z(level, len(harmonics))
    left = [held.position[a:b] - held.position[a:b].mean() for a, b in stretches]
    kept, dropped = [], []
    for h in harmonics:
        name = _named(h)
        if not stretches:
            dropped.append(
                f"{name} dropped: the held-out data hold no standstill stretch of "
                f"{MIN_STRETCH:g} s to confirm it"
            )
            continue
        waves = [
            h.amplitude_m * np.sin(2 * np.pi * h.frequency_hz * t + h.phase_rad) for t in times
        ]
        after = [r - (w - w.mean()) for r, w in zip(left, waves, strict=True)]
        z = _confirmation_z(left, after, duration, dt)
        if z >= needed:
            kept.append(h)
            left = after
        else:
            dropped.append(
                f"{name} dropped: not confirmed at the held-out standstill (evidence z "
                f"{z:.2g}, needed {needed:.2g}; residual RMS {_rms_nm(left)} nm without it, "
                f"{_rms_nm(after)} nm with it)"
            )
    return kept, dropped


def _confirmation_z(
    before: Sequence[np.ndarray], after: Sequence[np.ndarray], duration_s: float, dt: float
) -> float:
    """Evidence (z) that the residual pieces ``after`` (m) hold less energy than ``before``
    beyond chance, with what ``after`` holds taken as the noise, one independent sample per
    its correlation time (:func:`~twin_cosim.gap.floors.evidence.correlation_time`;
    ``duration_s``: the pieces' length, s; ``dt``: the sample period, s)."""
    left, found = np.concatenate(after), np.concatenate(before)
    scale = float(np.sqrt(np.sum(left**2)))
    if scale == 0.0:
        return math.inf
    spacing = correlation_time(list(after), dt)
    counted = duration_s * EFFECTIVE_SAMPLE_SPACING_S / spacing  # as improvement_z counts
    return improvement_z(found / scale, left / scale, counted, signals=1)


def _named(harmonic: Harmonic) -> str:
    """'noise harmonic 109 nm at 5.888 Hz': the amplitude in nm, the frequency in Hz."""
    return f"noise harmonic {1e9 * harmonic.amplitude_m:.3g} nm at {harmonic.frequency_hz:.4g} Hz"


def _rms_nm(pieces: Sequence[np.ndarray]) -> str:
    """RMS of the pieces (m) together, written in nm to three digits."""
    values = np.concatenate(pieces)
    return f"{1e9 * float(np.sqrt(np.mean(values**2))):.3g}"


def _out_of_range(values: dict[str, float], ranges: dict[str, tuple[float, float]]) -> str:
    """'' when every value is finite and inside its range, else what is wrong."""
    for name, value in values.items():
        if name not in ranges:
            return f"the plant has no parameter {name}"
        low, high = ranges[name]
        if not math.isfinite(value) or not low <= value <= high:
            return f"{name} = {value:.5g} outside [{low:g}, {high:g}]"
    return ""


def high_frequency_sigma(t: np.ndarray, residual: np.ndarray, dt: float) -> float:
    """Robust spread of white noise in a residual from its second differences (unit of it).

    Differences across a jump in time (between concatenated runs) are left out.
    """
    if len(residual) < 3:
        return 0.0
    second = residual[2:] - 2.0 * residual[1:-1] + residual[:-2]
    gaps = np.abs(np.diff(t) - dt) > 0.5 * dt
    regular = ~(gaps[1:] | gaps[:-1])
    second = second[regular]
    if len(second) == 0:
        return 0.0
    mad = float(np.median(np.abs(second - np.median(second))))
    return MAD_TO_SIGMA * mad / SECOND_DIFFERENCE_GAIN


def repeat_floor(groups: Sequence[Sequence[np.ndarray]]) -> float:
    """The spread of repeated runs' residuals around their mean, the unit of the residuals.

    Parameters
    ----------
    groups
        Per group of repeats (runs with the same input), each run's residual, sample by sample
        on the same grid (the shortest length counts); groups of fewer than two are left out.

    Returns
    -------
    float
        1.4826 x the median absolute deviation of every sample's departure from its group's
        mean, times sqrt(k / (k - 1)) for k repeats (a departure from the mean of k has the
        spread of one run's noise times sqrt((k - 1) / k)); 0.0 without a group of two.
    """
    departures = []
    for group in groups:
        if len(group) < 2:
            continue
        n = min(len(r) for r in group)
        stack = np.stack([np.asarray(r[:n], dtype=float) for r in group])
        k = len(group)
        departures.append(((stack - stack.mean(axis=0)) * math.sqrt(k / (k - 1))).ravel())
    if not departures:
        return 0.0
    found = np.concatenate(departures)
    return MAD_TO_SIGMA * float(np.median(np.abs(found - np.median(found))))


def noise_floors(
    res: Residuals,
    dt: float,
    resolution: float,
    repeats: Sequence[Sequence[Residuals]] = (),
) -> Floors:
    """The floors sigma_x (m) and sigma_i (A, or rad/s) of a training residual (see the module
    docstring).

    Parameters
    ----------
    res : Residuals
        Training residual against the replay with the noise model.
    dt : float
        Sample period, s.
    resolution : float
        Encoder grid of the measured position, m (0: not on a grid).
    repeats : sequence of sequences of Residuals
        Groups of the training runs' residuals that repeat one input (each run's own); none:
        the floors come from the high-frequency part of ``res``.
    """
    groups = [g for g in repeats if len(g) >= 2]
    runs = sum(len(g) for g in groups)
    floors = []
    for label in ("position", "current"):
        values = getattr(res, label)
        if groups:
            sigma = repeat_floor([[getattr(r, label) for r in g] for g in groups])
            source = (
                f"repeats: the spread of {runs} runs around the mean of their repeats "
                f"({len(groups)} group{'s' if len(groups) > 1 else ''} of one input)"
            )
        else:
            sigma = high_frequency_sigma(res.t, values, dt)
            source = "high-frequency part of the residual (second differences)"
        if label == "position" and resolution > 0 and sigma < resolution * QUANTISATION_GAIN:
            sigma = resolution * QUANTISATION_GAIN
            source = f"encoder quantisation noise (grid {resolution:.3g} m / sqrt(12))"
        floors.append((sigma, source))
    (sigma_x, source_x), (sigma_i, source_i) = floors
    return Floors(
        max(sigma_x, MIN_SIGMA_POSITION), max(sigma_i, MIN_SIGMA_CURRENT), source_x, source_i
    )


@dataclass(frozen=True)
class MetricComparison:
    """E_pk, ITAE and IAU of a measured run and of the twin with noise, and the verdict.

    Attributes
    ----------
    run : str
        The measured run.
    measured, twin : dict
        Metrics of the run and mean metrics of the noisy replays (E_pk um, ITAE um.s^2, IAU A.s).
    relative_error : dict
        |twin - measured| / |measured| per metric.
    noise_spread : dict
        Standard deviation of the noisy replays' metric / |measured|.
    threshold : dict
        significance_metric + significance_noise x noise_spread per metric.
    """

    run: str
    measured: dict[str, float]
    twin: dict[str, float]
    relative_error: dict[str, float]
    noise_spread: dict[str, float]
    threshold: dict[str, float]

    @property
    def largest_relative_error(self) -> float:
        """The largest relative error of the metrics (0 for a run without them)."""
        return max(self.relative_error.values(), default=0.0)

    @property
    def off(self) -> list[str]:
        """The metrics whose relative error exceeds their threshold."""
        return [k for k, v in self.relative_error.items() if v > self.threshold[k]]


def compare_metrics(
    run: MeasuredRun,
    record: RunRecord,
    floors: Floors,
    settings: DiagnosisSettings,
    seed: int = 0,
) -> MetricComparison:
    """The measured metrics against the twin's with white noise at the floors; none for an
    open-loop run (no reference it follows, no command of its own: its figures are the
    residual's)."""
    if run.drive is not None:
        return MetricComparison(run.source, {}, {}, {}, {}, {})
    measured = run_metrics(run.t, run.x_ref - run.x, run.current)
    x_sim = sim_at(record, "x", run.t)
    i_sim = sim_at(record, "current", run.t)
    rng = np.random.default_rng(seed)
    draws = [
        run_metrics(
            run.t,
            run.x_ref - (x_sim + rng.normal(0.0, floors.sigma_position_m, len(run.t))),
            i_sim + rng.normal(0.0, floors.sigma_current, len(run.t)),
        )
        for _ in range(settings.noise_draws)
    ]
    twin, relative, spread, threshold = {}, {}, {}, {}
    for key, value in measured.items():
        values = np.array([d[key] for d in draws])
        scale = abs(value) if value else 1.0
        twin[key] = float(values.mean())
        relative[key] = abs(twin[key] - value) / scale
        spread[key] = float(values.std(ddof=1)) / scale if len(values) > 1 else 0.0
        threshold[key] = settings.significance_metric + settings.significance_noise * spread[key]
    return MetricComparison(run.source, measured, twin, relative, spread, threshold)


def metrics_off(comparisons: list[MetricComparison]) -> bool:
    """A figure of merit (E_pk, ITAE, IAU) of some held-out run is off beyond what noise makes."""
    return any(c.off for c in comparisons)
