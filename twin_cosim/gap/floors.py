"""The noise stage: the measured noise as plant parameters, the noise floors, and what noise alone
does to the figures of merit (so that noise is never called a gap).

- Noise harmonics (:func:`twin_cosim.gap.noise.noise_harmonics`) identified at standstill become
  plant parameters only when every value lies in the FMU's variable ranges and the frequency
  below the Nyquist frequency of the run; a harmonic that cannot be identified is dropped and
  reported, never written to the FMU.
- Noise floors sigma_x (m), sigma_i (A) normalise every residual. They come, in this order, from
  the residual at standstill (robust spread, :func:`twin_cosim.gap.noise.noise_floor`), or,
  for a run without standstill, from the high-frequency part of the residual: the robust spread
  of its second difference divided by sqrt(6) (white noise of spread s gives second
  differences of spread sqrt(6) s, a smooth model error almost none). Neither falls below the
  encoder's quantisation noise q / sqrt(12) when the position lies on a grid of step q. The source
  of each floor is reported.
- Significance: the measured E_pk, ITAE and IAU are compared with the twin's, computed on the
  replay plus ``noise_draws`` seeded draws of white noise at the floors (noise makes |e| and |i|
  larger on average, which alone moves ITAE and IAU by a few percent); a metric is off when its
  relative error exceeds ``significance_metric`` plus ``significance_noise`` standard deviations
  of its noise-only spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from twin_cosim.gap import noise as noise_model
from twin_cosim.gap import regimes as regime_model
from twin_cosim.gap.residuals import Residuals, run_metrics, sim_at
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.measured import MeasuredRun
from twin_cosim.run_record import RunRecord

SECOND_DIFFERENCE_GAIN = math.sqrt(6.0)  # spread of x[k+1] - 2 x[k] + x[k-1] for white x
QUANTISATION_GAIN = 1.0 / math.sqrt(12.0)  # spread of the rounding error of a grid of step 1
MIN_SIGMA_POSITION = 1e-12  # m, guards a perfect replay of noise-free data
MIN_SIGMA_CURRENT = 1e-9  # A


@dataclass(frozen=True)
class NoiseModel:
    """Noise harmonics accepted as plant parameters, and those dropped with the reason."""

    harmonics: list[noise_model.Harmonic]
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
    dt: float,
    ranges: dict[str, tuple[float, float]],
    start_values: dict[str, float],
) -> NoiseModel:
    """Noise harmonics of the measured position at standstill, checked against the FMU's ranges.

    Parameters
    ----------
    raw : Residuals
        Training residual against the replay without noise model (its position is measured
        minus noise-free simulated, so at standstill it is the measured noise).
    dt : float
        Sample period, s.
    ranges : dict
        (min, max) of the FMU parameters by name.
    start_values : dict
        The FMU's parameter values (the number of harmonic slots and their defaults).
    """
    slots = noise_model.plant_slots(start_values)
    if slots == 0:
        return NoiseModel([], {}, [])  # the plant model has no noise harmonics to set
    still = raw.regimes == regime_model.STANDSTILL
    try:
        found = noise_model.noise_harmonics(raw.t, raw.position, still, count=slots)
    except ValueError as exc:
        return NoiseModel([], {}, [f"noise harmonics not identified: {exc}"])
    nyquist = 0.5 / dt
    kept, dropped = [], []
    for harmonic in found[:slots]:
        slot = noise_model.as_plant_parameters([*kept, harmonic], start_values)
        problem = _out_of_range(slot, ranges)
        if not 0.0 < harmonic.frequency_hz < nyquist:
            problem = f"frequency {harmonic.frequency_hz:.4g} Hz outside (0, {nyquist:.4g}) Hz"
        if problem:
            dropped.append(
                f"noise harmonic {harmonic.amplitude_m:.3g} m at {harmonic.frequency_hz:.4g} Hz "
                f"dropped: {problem}"
            )
        else:
            kept.append(harmonic)
    parameters = noise_model.as_plant_parameters(kept, start_values) if kept else {}
    return NoiseModel(kept, parameters, dropped)


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
    return noise_model.MAD_TO_SIGMA * mad / SECOND_DIFFERENCE_GAIN


def noise_floors(res: Residuals, dt: float, resolution: float) -> Floors:
    """The floors sigma_x (m) and sigma_i (A) of a training residual (see the module docstring).

    Parameters
    ----------
    res : Residuals
        Training residual against the replay with the noise model.
    dt : float
        Sample period, s.
    resolution : float
        Encoder grid of the measured position, m (0: not on a grid).
    """
    still = res.regimes == regime_model.STANDSTILL
    floors = []
    for values, label in ((res.position, "position"), (res.current, "current")):
        sigma = noise_model.noise_floor(values, still) if still.any() else 0.0
        source = "robust spread of the residual at standstill"
        if sigma <= 0.0:
            sigma = high_frequency_sigma(res.t, values, dt)
            source = "high-frequency part of the residual (second differences; no standstill)"
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
        """The largest relative error of the three metrics."""
        return max(self.relative_error.values())

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
    """The measured metrics against the twin's with white noise at the floors."""
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
