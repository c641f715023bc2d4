"""Where the gap lies: by motion regime, by position along the axis, by order and frequency.

- Regimes: share of time and of residual energy per regime (:mod:`twin_cosim.gap.data.regimes`).
- Along the axis: the normalised residual energy 0.5 ((r_x / sigma_x)^2 + (r_i / sigma_i)^2)
  of the moving samples, reversal and breakaway windows left out (their residual belongs to the
  event, not to the place), binned over the measured carriage position (``axis_bin`` wide)
  separately for each direction of motion. A bin whose mean energy reaches ``axis_enrichment``
  times the median bin's is a concentration; neighbouring concentrated bins (one quiet bin
  between them allowed) form a span, trimmed to the bins around its peak that reach a tenth of
  the peak's energy (the residual trails a local defect in the direction of motion as the loop
  recovers; the trimming keeps the span on the defect). Spans found in both directions that
  overlap are one span of direction 0. Each span's ``energy_share`` is its share of the binned
  energy above the median level (what is there beyond the even spread); spans below
  ``axis_min_share`` of it are not named; largest first. A span whose energy lies mostly
  where a stroke starts or ends (the axis speeds up from a stop or a reversal, or slows into
  one: an end of travel) is marked ``at_stroke_end``: the speed there is low, and a
  speed-dependent effect (friction near v = 0) concentrates there as a local defect would.
- Orders and frequencies: order spectra of the motor and screw angle and a spectrum in Hz on the
  constant-velocity stretches, with the position-periodic / temporal rule of
  :func:`twin_cosim.gap.spectra.periodicity`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from twin_cosim.gap import spectra
from twin_cosim.gap.data import regimes as regime_model
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.settings import DiagnosisSettings

MM_PER_M = 1e3
MIN_BIN_SAMPLES = 4  # a bin with fewer moving samples in a direction is not judged
PEAK_FRACTION = 0.1  # a span keeps the bins around its peak above this share of the peak's energy


@dataclass(frozen=True)
class AxisSpan:
    """A stretch of the axis where the residual is concentrated.

    Attributes
    ----------
    from_mm, to_mm : float
        Ends of the span (carriage position), mm.
    direction : int
        +1 or -1 when it shows moving that way only, 0 when in both directions.
    energy_share : float
        Share of the binned residual energy above the median level that lies in the span.
    enrichment : float
        Mean energy in the span over the median bin's.
    at_stroke_end : bool
        Most of its energy lies where a stroke starts or ends (:func:`stroke_ends`).
    """

    from_mm: float
    to_mm: float
    direction: int
    energy_share: float
    enrichment: float
    at_stroke_end: bool = False


@dataclass(frozen=True)
class Location:
    """Where the residual lies (see the module docstring)."""

    position: dict[str, dict[str, float]]
    current: dict[str, dict[str, float]]
    along_axis: list[AxisSpan]
    periodicity: dict[str, Any]


def _bin_energy(
    x: np.ndarray, energy: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Sum of energy and sample count per bin."""
    index = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    total = np.bincount(index, weights=energy, minlength=len(edges) - 1)
    count = np.bincount(index, minlength=len(edges) - 1)
    return total, count


@dataclass(frozen=True)
class _Found:
    """A span of one direction (or merged) before it is judged: ends (m), direction, energy
    above the median level, enrichment, energy, and energy near turns (normalised units)."""

    start: float
    stop: float
    direction: int
    excess: float
    enrichment: float
    energy: float
    at_turns: float


def stroke_ends(res: Residuals) -> np.ndarray:
    """True for the samples where a stroke starts or ends: the axis speeds up from a stop or a
    reversal, or slows into one.

    Of each stroke (:func:`twin_cosim.gap.data.regimes.strokes`), the samples before its first and
    after its last constant-velocity sample (all of them without one), except at the ends of
    the record when it is moving there (the motion began before or goes on after it).
    """
    flags = np.zeros(len(res.t), dtype=bool)
    cruising = res.regimes == regime_model.CONSTANT_VELOCITY
    for a, b, _ in regime_model.strokes(res.direction, res.x):
        steady = np.flatnonzero(cruising[a:b])
        if a > 0:
            flags[a : a + (steady[0] if len(steady) else b - a)] = True
        if b < len(res.t):
            flags[a + (steady[-1] + 1 if len(steady) else 0) : b] = True
    return flags


def _spans_of(flagged: np.ndarray, mean: np.ndarray) -> list[tuple[int, int]]:
    """[first, last] bin ranges of flagged bins (bridging single quiet bins), each trimmed to
    the bins around its peak that reach PEAK_FRACTION of the peak's mean energy."""
    spans: list[list[int]] = []
    for i in np.flatnonzero(flagged):
        if spans and i - spans[-1][1] <= 2:
            spans[-1][1] = int(i)
        else:
            spans.append([int(i), int(i)])
    trimmed = []
    for a, b in spans:
        peak = a + int(np.argmax(mean[a : b + 1]))
        strong = mean >= PEAK_FRACTION * mean[peak]
        first, last = peak, peak
        while first > a and strong[first - 1]:
            first -= 1
        while last < b and strong[last + 1]:
            last += 1
        trimmed.append((first, last))
    return trimmed


def along_axis(
    res: Residuals, sigma_x: float, sigma_i: float, settings: DiagnosisSettings
) -> list[AxisSpan]:
    """Spans of the axis where the residual is concentrated, largest first."""
    excluded = (res.regimes == regime_model.REVERSAL) | (res.regimes == regime_model.BREAKAWAY)
    moving = (res.direction != 0) & ~excluded
    if moving.sum() < 10 * MIN_BIN_SAMPLES:
        return []
    x = res.x[moving]
    low, high = float(x.min()), float(x.max())
    if high - low < 3 * settings.axis_bin:
        return []
    edges = np.arange(low, high + settings.axis_bin, settings.axis_bin)
    energy = res.normalised_energy(sigma_x, sigma_i)[moving]
    turning = stroke_ends(res)[moving]
    direction = res.direction[moving]
    found: list[_Found] = []
    excess_total = 0.0
    per_direction = []
    for sign in (1, -1):
        inside = direction == sign
        total, count = _bin_energy(x[inside], energy[inside], edges)
        at_turns, _ = _bin_energy(x[inside], np.where(turning[inside], energy[inside], 0.0), edges)
        judged = count >= MIN_BIN_SAMPLES
        if judged.sum() < 3:
            continue
        mean = np.where(judged, total / np.maximum(count, 1), 0.0)
        level = float(np.median(mean[judged]))
        excess = np.where(judged, np.maximum(total - level * count, 0.0), 0.0)
        excess_total += float(excess.sum())
        flagged = judged & (mean >= settings.axis_enrichment * max(level, 1e-300))
        per_direction.append((sign, flagged, excess, mean, level, total, at_turns))
    for sign, flagged, excess, mean, level, total, at_turns in per_direction:
        for a, b in _spans_of(flagged, mean):
            found.append(
                _Found(
                    float(edges[a]),
                    float(edges[b + 1]),
                    sign,
                    float(excess[a : b + 1].sum()),
                    float(mean[a : b + 1].max() / max(level, 1e-300)),
                    float(total[a : b + 1].sum()),
                    float(at_turns[a : b + 1].sum()),
                )
            )
    spans = _merge_directions(found)
    if excess_total <= 0:
        return []
    result = [
        AxisSpan(
            f.start * MM_PER_M,
            f.stop * MM_PER_M,
            f.direction,
            f.excess / excess_total,
            f.enrichment,
            f.at_turns > 0.5 * f.energy,
        )
        for f in spans
        if f.excess >= settings.axis_min_share * excess_total
    ]
    return sorted(result, key=lambda s: -s.energy_share)


def _merge_directions(spans: list[_Found]) -> list[_Found]:
    """Spans of the two directions that overlap become one span of direction 0."""
    plus = [s for s in spans if s.direction == 1]
    minus = [s for s in spans if s.direction == -1]
    merged, used = [], set()
    for p in plus:
        partners = [i for i, m in enumerate(minus) if m.start < p.stop and p.start < m.stop]
        if not partners:
            merged.append(p)
            continue
        group = [p] + [minus[i] for i in partners]
        used.update(partners)
        merged.append(
            _Found(
                min(s.start for s in group),
                max(s.stop for s in group),
                0,
                sum(s.excess for s in group),
                max(s.enrichment for s in group),
                sum(s.energy for s in group),
                sum(s.at_turns for s in group),
            )
        )
    merged += [m for i, m in enumerate(minus) if i not in used]
    return merged


def speed_groups(res: Residuals, dt: float) -> list[tuple[float, list[tuple[int, int]]]]:
    """Constant-velocity stretches grouped by speed level (within 10 %): each level's motor
    speed (rad/s, its first stretch's) and its stretches."""
    stretches = regime_model.segments(res.regimes, regime_model.CONSTANT_VELOCITY)
    levels: list[tuple[float, list[tuple[int, int]]]] = []
    for start, stop in stretches:
        if stop - start < 2:
            continue
        angle = res.motor_angle[start:stop]
        speed = abs(angle[-1] - angle[0]) / ((stop - start - 1) * dt)
        for level, members in levels:
            if abs(speed - level) <= 0.1 * level:
                members.append((start, stop))
                break
        else:
            levels.append((speed, [(start, stop)]))
    return levels


def dominant_order(res: Residuals, signal: np.ndarray, angle: np.ndarray) -> float | None:
    """The whole order (>= 1) of the dominant peak of a residual's order spectrum, or None."""
    stretches = regime_model.segments(res.regimes, regime_model.CONSTANT_VELOCITY)
    orders, amplitude = spectra.order_spectrum(signal, angle, stretches)
    if len(orders) == 0:
        return None
    peak = spectra.dominant_peak(orders, amplitude)
    return float(max(1, round(peak.location))) if peak else None


def _jsonable_periodicity(value: Any) -> Any:
    if hasattr(value, "__dataclass_fields__"):
        return asdict(value)
    if isinstance(value, dict):
        return {k: _jsonable_periodicity(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_jsonable_periodicity(v) for v in value]
    return value


def locate(
    res: Residuals,
    sigma_x: float,
    sigma_i: float,
    screw_angle: Callable[[np.ndarray], np.ndarray],
    dt: float,
    settings: DiagnosisSettings,
    travel: bool = True,
) -> Location:
    """Regime shares, along-axis spans and periodicity of a residual; no spans where the
    position does not run along an axis (``travel`` False: a rotor's angle,
    :attr:`~twin_cosim.measured.PositionLabel.travel`)."""
    levels = speed_groups(res, dt)
    groups, speeds = [members for _, members in levels], [speed for speed, _ in levels]
    periodicity = {}
    for signal, residual in (("position", res.position), ("current", res.current)):
        for angle_name, angle in (
            ("motor", res.motor_angle),
            ("screw", screw_angle(res.motor_angle)),
        ):
            verdict = spectra.periodicity(residual, angle, dt, groups, speeds=speeds)
            periodicity[f"{signal}_vs_{angle_name}_angle"] = _jsonable_periodicity(verdict)
    return Location(
        regime_model.energy_shares(res.position, res.regimes),
        regime_model.energy_shares(res.current, res.regimes),
        along_axis(res, sigma_x, sigma_i, settings) if travel else [],
        periodicity,
    )
