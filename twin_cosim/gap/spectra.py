"""Spectra of a residual in Hz and in orders of an angle: is the gap position-periodic or temporal?

All spectra here are single-sided amplitude spectra: a sine of amplitude A (m or A, the unit of
the residual) shows as a peak of height A. Each stretch of data loses its mean
(:func:`frequency_spectrum`) or its linear trend (order spectra, speed groups), is weighted with a
periodic Hann window and zero-padded to at least four times its length before the FFT; the
amplitude is corrected by the window's coherent gain (2 |X| / sum w). The padding interpolates
the spectrum to a quarter of the natural bin, which keeps the Hann scalloping loss below 1%
(15% without padding). Several stretches are averaged as amplitude spectra on one common grid,
weighted by their length.

An *order* is a number of cycles per revolution of the angle given (motor or leadscrew angle). In
the order spectrum each constant-velocity segment is resampled on a uniform grid of the angle
(linear interpolation), so that an effect tied to the position keeps its order whatever the
speed, while an effect at a fixed frequency f moves to the order f / (revolutions per second).
:func:`periodicity` uses this: a peak whose order stays put across speed levels while its
frequency moves is position-periodic; one whose frequency stays put is temporal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

import numpy as np

# scipy.signal is imported where a spectrum is computed, not here: it pulls scipy.stats in (about
# 0.4 s), which every replay worker importing the residuals would pay at its start for spectra
# it never computes.

PADDING = 4  # the FFT length is at least PADDING times the longest stretch
MIN_REVOLUTIONS = 2.0  # shorter segments are left out of order spectra
AGREE = 0.05  # peaks agree across speed groups when max / min - 1 <= AGREE
DIFFER = 0.10  # and differ when max / min - 1 > DIFFER

Segment = tuple[int, int]


@dataclass(frozen=True)
class Peak:
    """A spectral peak.

    Attributes
    ----------
    location : float
        Position on the spectrum's axis: Hz or order (cycles per revolution), refined between
        bins by a parabola through the peak bin and its neighbours.
    amplitude : float
        Height of the peak, unit of the residual (m or A).
    ratio : float
        Height over the median of the spectrum without its DC bin, dimensionless.
    """

    location: float
    amplitude: float
    ratio: float


class GroupPeaks(TypedDict):
    """Dominant peaks of one speed group (None: no significant peak)."""

    order: Peak | None
    frequency_hz: Peak | None


class Periodicity(TypedDict):
    """Verdict of :func:`periodicity` with the peaks it rests on."""

    verdict: str  # "position-periodic", "temporal" or "inconclusive"
    groups: list[GroupPeaks]
    reason: str


def mean_amplitude_spectrum(
    pieces: Sequence[np.ndarray], step: float, weights: Sequence[float] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean of the Hann amplitude spectra of detrended pieces on one common grid.

    Parameters
    ----------
    pieces : Sequence[np.ndarray]
        Uniformly sampled stretches, already detrended, each at least 2 samples (m or A).
    step : float
        Sample spacing of every piece, in s or in revolutions.
    weights : Sequence[float] | None
        Weight of each piece (None: equal weights).

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        Axis in cycles per unit of ``step`` (Hz or orders) and amplitude (unit of the pieces).
    """
    from scipy.signal import get_window

    weights = np.ones(len(pieces)) if weights is None else np.asarray(weights, dtype=float)
    length = 1 << int(np.ceil(np.log2(PADDING * max(len(p) for p in pieces))))
    amplitude = np.zeros(length // 2 + 1)
    for piece, weight in zip(pieces, weights, strict=True):
        window = get_window("hann", len(piece))
        spectrum = np.abs(np.fft.rfft(piece * window, n=length)) / window.sum()
        spectrum[1:-1] *= 2.0  # single-sided; DC and Nyquist bins have no mirror image
        amplitude += weight * spectrum
    return np.fft.rfftfreq(length, step), amplitude / weights.sum()


def frequency_spectrum(residual: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude spectrum of a residual in Hz, mean removed (see the module docstring).

    Parameters
    ----------
    residual : np.ndarray
        Uniformly sampled residual, m or A, at least 2 samples.
    dt : float
        Sample spacing, s.

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        Frequency, Hz, and amplitude, unit of the residual.

    Raises
    ------
    ValueError
        When the residual is not 1-D or has fewer than 2 samples.
    """
    residual = np.asarray(residual, dtype=float)
    if residual.ndim != 1 or residual.size < 2:
        raise ValueError("the residual must be a 1-D array of at least 2 samples")
    return mean_amplitude_spectrum([residual - residual.mean()], dt)


def _usable(angle: np.ndarray, segment: Segment) -> bool:
    """Whether the angle (rad) moves strictly one way over the segment, MIN_REVOLUTIONS at least."""
    steps = np.diff(angle[segment[0] : segment[1]])
    monotonic = steps.size > 0 and (np.all(steps > 0.0) or np.all(steps < 0.0))
    return bool(monotonic) and abs(float(steps.sum())) >= 2.0 * np.pi * MIN_REVOLUTIONS


def _usable_segments(angle: np.ndarray, segments: Sequence[Segment]) -> list[Segment]:
    """The segments an order spectrum can use (see :func:`_usable`)."""
    return [s for s in segments if _usable(angle, s)]


def _resample_on_angle(
    residual: np.ndarray, angle: np.ndarray, samples_per_revolution: int
) -> np.ndarray:
    """Residual interpolated on a uniform grid of the angle (rad), linear trend removed."""
    from scipy.signal import detrend

    if angle[-1] < angle[0]:  # negative speed: walk the segment backwards
        angle, residual = angle[::-1], residual[::-1]
    spacing = 2.0 * np.pi / samples_per_revolution
    grid = angle[0] + spacing * np.arange(int((angle[-1] - angle[0]) / spacing) + 1)
    return detrend(np.interp(grid, angle, residual), type="linear")


def order_spectrum(
    residual: np.ndarray,
    angle: np.ndarray,
    segments: Sequence[Segment],
    samples_per_revolution: int = 64,
    max_order: float = 50,
) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude spectrum of the residual in orders of ``angle``, averaged over segments.

    Parameters
    ----------
    residual : np.ndarray
        Residual per sample, m or A.
    angle : np.ndarray
        Angle per sample, rad (motor or leadscrew), increasing or decreasing.
    segments : Sequence[tuple[int, int]]
        [start, stop) index ranges, typically constant-velocity stretches; those sweeping
        fewer than 2 revolutions or over which the angle is not strictly monotonic (a stall or
        a jump) are left out.
    samples_per_revolution : int
        Resolution of the uniform angle grid. Orders above half of it are not resolved.
    max_order : float
        Highest order returned, cycles per revolution; capped at samples_per_revolution / 2.

    Returns
    -------
    tuple[np.ndarray, np.ndarray]
        Order, cycles per revolution, and amplitude, unit of the residual; the amplitude spectra
        of the segments are weighted by their length in revolutions. Empty when no segment is
        usable.

    Raises
    ------
    ValueError
        When residual and angle are not 1-D arrays of one length.
    """
    residual, angle = np.asarray(residual, dtype=float), np.asarray(angle, dtype=float)
    if residual.shape != angle.shape or residual.ndim != 1:
        raise ValueError("residual and angle must be 1-D arrays of one length")
    used = _usable_segments(angle, segments)
    if not used:
        return np.empty(0), np.empty(0)
    pieces = [
        _resample_on_angle(residual[a:b], angle[a:b], samples_per_revolution) for a, b in used
    ]
    weights = [(len(p) - 1) / samples_per_revolution for p in pieces]
    order, amplitude = mean_amplitude_spectrum(pieces, 1.0 / samples_per_revolution, weights)
    keep = order <= min(max_order, samples_per_revolution / 2)
    return order[keep], amplitude[keep]


def dominant_peak(x_axis: np.ndarray, amplitude: np.ndarray, min_ratio: float = 5.0) -> Peak | None:
    """The largest peak outside the DC bin, if it stands ``min_ratio`` above the median.

    Parameters
    ----------
    x_axis : np.ndarray
        Uniformly spaced axis of the spectrum (Hz or orders); the bin at 0 is ignored.
    amplitude : np.ndarray
        Amplitude spectrum, unit of the residual.
    min_ratio : float
        Least ratio of the peak to the median amplitude, dimensionless.

    Returns
    -------
    Peak | None
        The peak, or None when the spectrum is empty, zero or has no significant peak.
    """
    x_axis, amplitude = np.asarray(x_axis, dtype=float), np.asarray(amplitude, dtype=float)
    body = np.flatnonzero(x_axis != 0.0)
    if body.size == 0:
        return None
    index = int(body[np.argmax(amplitude[body])])
    location, height = _refine(x_axis, amplitude, index)
    median = float(np.median(amplitude[body]))
    if height <= 0.0:
        return None
    ratio = height / median if median > 0.0 else np.inf
    return Peak(location, height, ratio) if ratio >= min_ratio else None


def _refine(x_axis: np.ndarray, amplitude: np.ndarray, index: int) -> tuple[float, float]:
    """Vertex of the parabola through a peak bin and its neighbours: location and height."""
    if index == 0 or index == len(amplitude) - 1:
        return float(x_axis[index]), float(amplitude[index])
    left, centre, right = amplitude[index - 1 : index + 2]
    curvature = left - 2.0 * centre + right
    offset = 0.5 * (left - right) / curvature if curvature < 0.0 else 0.0
    spacing = x_axis[index + 1] - x_axis[index]
    return float(x_axis[index] + offset * spacing), float(centre - 0.25 * (left - right) * offset)


def _spread(values: list[float]) -> float:
    """Relative spread max / min - 1 of positive values."""
    return max(values) / min(values) - 1.0


def _group_peaks(
    residual: np.ndarray,
    angle: np.ndarray,
    dt: float,
    group: Sequence[Segment],
    min_ratio: float,
) -> GroupPeaks:
    """Dominant order and Hz peaks of one speed group (the same usable segments for both)."""
    order, amplitude = order_spectrum(residual, angle, group)
    used = _usable_segments(angle, group)
    if not used:
        return {"order": None, "frequency_hz": None}
    from scipy.signal import detrend

    pieces = [detrend(residual[a:b], type="linear") for a, b in used]
    frequency, spectrum = mean_amplitude_spectrum(pieces, dt, [b - a for a, b in used])
    return {
        "order": dominant_peak(order, amplitude, min_ratio),
        "frequency_hz": dominant_peak(frequency, spectrum, min_ratio),
    }


def periodicity(
    residual: np.ndarray,
    angle: np.ndarray,
    dt: float,
    speed_groups: Sequence[Sequence[Segment]],
    min_ratio: float = 5.0,
    speeds: Sequence[float] = (),
) -> Periodicity:
    """Tell a position-periodic residual from a temporal one across speed levels.

    For each speed group (the constant-velocity segments at one speed level) the dominant peak
    of the order spectrum and of the Hz spectrum (Hann amplitude spectra of the same segments,
    detrended, averaged weighted by duration) are found with :func:`dominant_peak`. Peaks agree
    across groups when max / min - 1 <= 5% and differ when it exceeds 10%.

    Parameters
    ----------
    residual : np.ndarray
        Residual per sample, m or A.
    angle : np.ndarray
        Angle per sample, rad (orders are cycles per revolution of it).
    dt : float
        Sample spacing, s.
    speed_groups : Sequence[Sequence[tuple[int, int]]]
        One list of [start, stop) index segments per constant-speed level.
    min_ratio : float
        Least peak-to-median ratio of a significant peak, dimensionless.
    speeds : Sequence[float]
        The speed of each group (rad/s of the angle), named in the reason when given.

    Returns
    -------
    Periodicity
        ``verdict``: "position-periodic" (orders agree, frequencies differ), "temporal"
        (frequencies agree, orders differ) or "inconclusive" (anything else, fewer than two
        groups, or a group without a significant peak); ``groups``: the peaks per group;
        ``reason``: one sentence.
    """
    residual, angle = np.asarray(residual, dtype=float), np.asarray(angle, dtype=float)
    groups = [_group_peaks(residual, angle, dt, g, min_ratio) for g in speed_groups]
    if len(groups) < 2:
        return _verdict("inconclusive", groups, "fewer than two speed groups")
    for k, group in enumerate(groups):
        for kind, peak in group.items():
            if peak is None:
                level = f"at {speeds[k]:.3g} rad/s, " if k < len(speeds) else ""
                reason = (
                    f"no significant {kind} peak (ratio >= {min_ratio:g}) in speed group "
                    f"{k + 1} of {len(groups)} ({level}its constant-velocity stretches)"
                )
                return _verdict("inconclusive", groups, reason)
    orders = [g["order"].location for g in groups]
    frequencies = [g["frequency_hz"].location for g in groups]
    order_spread, frequency_spread = _spread(orders), _spread(frequencies)
    spreads = f"order spread {order_spread:.1%}, frequency spread {frequency_spread:.1%}"
    if order_spread <= AGREE and frequency_spread > DIFFER:
        reason = f"the peak stays at order {np.mean(orders):.3g} across speeds ({spreads})"
        return _verdict("position-periodic", groups, reason)
    if frequency_spread <= AGREE and order_spread > DIFFER:
        reason = f"the peak stays at {np.mean(frequencies):.4g} Hz across speeds ({spreads})"
        return _verdict("temporal", groups, reason)
    if order_spread <= AGREE and frequency_spread <= AGREE:
        reason = f"order and frequency both agree: the speed levels are too close ({spreads})"
    else:
        reason = f"no fixed order with a moving frequency, nor the reverse ({spreads})"
    return _verdict("inconclusive", groups, reason)


def _verdict(verdict: str, groups: list[GroupPeaks], reason: str) -> Periodicity:
    """Assemble the result of :func:`periodicity`."""
    return {"verdict": verdict, "groups": groups, "reason": reason}
