"""Reference trajectories: position samples every 4 ms, cubic interpolation to the position loop;
the motion regimes a reference covers.

A reference is described either as segments (dwells, trapezoidal moves, cosine oscillations) or
as samples read from a CSV file. Either way the CNC's interpolator sees samples every
``sample_period`` (4 ms) and interpolates them with a cubic spline onto the position-loop grid
(250 us); the spline's first and second derivatives are the velocity and acceleration
feedforward.

An interpolated grid is kept in the per-user cache (``references/``) under a digest of
everything it is made from: the reference samples and periods, the interpolating code (this
file) and the versions of SciPy and numpy. A run of an unchanged reference reads it back (the
same bits) instead of importing SciPy and fitting the spline again. Each file is written under a
temporary name and renamed into place, so concurrent runs never read a partial one.

**The motion envelope**: the motion regimes a trajectory covers, and whether a held-out one
leaves those of the tuning.

Gains tuned on some trajectories hold on another where its motion stays within what they
covered: robust gains tuned on reference 1 and diagnosis.yaml broke down on trajectories that
start from a dwell at 0.5-0.7 m/s^2, a regime neither contains (docs/transfer.md). The envelope
of a reference is four figures, from its velocity and acceleration on the position-loop grid:

- ``speed``: the largest |v_ref|, m/s;
- ``acceleration``: the largest |a_ref|, m/s^2;
- ``reversal_acceleration``: the largest |a_ref| where v_ref changes sign without stopping
  (a reversal while moving), m/s^2;
- ``start_acceleration``: the largest |a_ref| within ``START_WINDOW`` of leaving a standstill of
  at least ``STANDSTILL`` (a start, or a reversal, after a dwell), m/s^2.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from fmu_build.build import cache_dir
from twin_cosim.versions import installed_version


class ReferenceError(ValueError):
    """A reference description or CSV is invalid; the message names the source and the item."""


@dataclass(frozen=True)
class Dwell:
    """Stand still for ``duration`` (s)."""

    duration: float


@dataclass(frozen=True)
class Move:
    """Trapezoidal move to the absolute position ``to`` (m) with speed and acceleration limits.

    ``velocity`` in m/s, ``acceleration`` in m/s^2; a short move becomes triangular.
    """

    to: float
    velocity: float
    acceleration: float


@dataclass(frozen=True)
class Oscillation:
    """``cycles`` cycles of x0 + amplitude (1 - cos(2 pi frequency t)) / 2: smooth reversals.

    ``amplitude`` (m, peak to peak, may be negative to go backwards first), ``frequency`` (Hz).
    """

    amplitude: float
    frequency: float
    cycles: float


@dataclass(frozen=True)
class Ramp:
    """Change the speed to ``velocity`` (m/s) at ``acceleration`` (m/s^2), then hold it.

    The segment lasts ``duration`` (s), which must cover the speed change. Ramps chain moves
    without stopping (velocity levels); dwells, moves and oscillations must start at rest.
    """

    velocity: float
    acceleration: float
    duration: float


Segment = Dwell | Move | Oscillation | Ramp
Profile = Callable[[np.ndarray], np.ndarray]


def _move_profile(distance: float, v_max: float, a_max: float) -> tuple[float, Profile]:
    """Duration (s) and relative position (m) of a rest-to-rest trapezoidal move."""
    sign = math.copysign(1.0, distance)
    d = abs(distance)
    t_acc = v_max / a_max
    if a_max * t_acc**2 >= d:  # triangular
        t_acc = math.sqrt(d / a_max)
        t_flat = 0.0
    else:
        t_flat = (d - a_max * t_acc**2) / v_max
    v_peak = a_max * t_acc
    duration = 2 * t_acc + t_flat

    def position(t: np.ndarray) -> np.ndarray:
        t = np.clip(t, 0.0, duration)
        up = 0.5 * a_max * np.minimum(t, t_acc) ** 2
        flat = v_peak * np.clip(t - t_acc, 0.0, t_flat)
        t_down = np.clip(t - t_acc - t_flat, 0.0, t_acc)
        down = v_peak * t_down - 0.5 * a_max * t_down**2
        return sign * (up + flat + down)

    return duration, position


def _ramp_profile(v0: float, ramp: Ramp, where: str) -> tuple[float, Profile]:
    t_ramp = abs(ramp.velocity - v0) / ramp.acceleration
    if t_ramp > ramp.duration + 1e-12:
        raise ReferenceError(
            f"{where}: the speed change from {v0} to {ramp.velocity} m/s takes {t_ramp:g} s at "
            f"{ramp.acceleration} m/s^2, longer than the segment's duration {ramp.duration} s"
        )
    a = math.copysign(ramp.acceleration, ramp.velocity - v0)

    def position(t: np.ndarray) -> np.ndarray:
        t = np.clip(t, 0.0, ramp.duration)
        t_r = np.minimum(t, t_ramp)
        return v0 * t_r + 0.5 * a * t_r**2 + ramp.velocity * (t - t_r)

    return ramp.duration, position


def _oscillation_profile(segment: Oscillation) -> tuple[float, Profile]:
    omega = 2 * math.pi * segment.frequency
    duration = segment.cycles / segment.frequency

    def position(t: np.ndarray) -> np.ndarray:
        return 0.5 * segment.amplitude * (1 - np.cos(omega * np.clip(t, 0.0, duration)))

    return duration, position


def _profile(segment: Segment, x0: float, v0: float, where: str) -> tuple[float, Profile, float]:
    """Duration (s), relative position function and end speed (m/s) of one segment."""
    if isinstance(segment, Ramp):
        duration, shape = _ramp_profile(v0, segment, where)
        return duration, shape, segment.velocity
    if v0 != 0.0:
        raise ReferenceError(
            f"{where}: starts at {v0} m/s; only a ramp may follow a ramp that ends moving"
        )
    if isinstance(segment, Dwell):
        return segment.duration, np.zeros_like, 0.0
    if isinstance(segment, Move):
        duration, shape = _move_profile(segment.to - x0, segment.velocity, segment.acceleration)
        return duration, shape, 0.0
    duration, shape = _oscillation_profile(segment)
    return duration, shape, 0.0


def segments_duration(segments: list[Segment], start_position: float = 0.0) -> float:
    """Duration (s) of segments starting at rest at ``start_position`` (m), without sampling.

    Raises
    ------
    ReferenceError
        As :func:`sample_segments` does for segments that cannot follow one another.
    """
    total, x0, v0 = 0.0, start_position, 0.0
    for index, segment in enumerate(segments):
        duration, shape, v0 = _profile(segment, x0, v0, f"segment {index}")
        x0 += float(shape(np.array([duration]))[0])
        total += duration
    return total


def sample_segments(
    segments: list[Segment], sample_period: float, start_position: float = 0.0
) -> np.ndarray:
    """Sample segments every ``sample_period`` (s), starting at rest at ``start_position`` (m).

    Returns
    -------
    numpy.ndarray
        Positions (m) at t = 0, T, 2T, ... up to the end of the last segment.

    Raises
    ------
    ReferenceError
        When the list is empty, a segment cannot follow the speed left by the one before, or the
        reference does not end at rest.
    """
    if not segments:
        raise ReferenceError("a reference needs at least one segment")
    pieces: list[tuple[float, float, Profile]] = []  # (start s, base position m, shape)
    t0, x0, v0 = 0.0, start_position, 0.0
    for index, segment in enumerate(segments):
        duration, shape, v_end = _profile(segment, x0, v0, f"segment {index}")
        pieces.append((t0, x0, shape))
        x0 += float(shape(np.array([duration]))[0])
        t0 += duration
        v0 = v_end
    if v0 != 0.0:
        raise ReferenceError(f"the reference ends moving at {v0} m/s; end with a ramp to 0")
    times = np.arange(int(math.floor(t0 / sample_period + 1e-9)) + 1) * sample_period
    positions = np.full(len(times), start_position)
    for start, base, shape in pieces:
        after = times >= start - 1e-12
        positions[after] = base + shape(times[after] - start)
    return positions


def read_reference_csv(path: Path, sample_period: float) -> np.ndarray:
    """Read reference samples from a CSV with columns ``t`` (s) and ``x_ref`` (m).

    The samples must be finite and equally spaced by ``sample_period`` starting at t = 0.
    """
    import pandas as pd  # a CSV reference only: pandas stays off the start of other runs

    try:
        table = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise ReferenceError(f"{path}: cannot read reference CSV: {exc}") from exc
    for column in ("t", "x_ref"):
        if column not in table.columns:
            raise ReferenceError(f"{path}: missing column {column!r} (expected t [s], x_ref [m])")
    t = pd.to_numeric(table["t"], errors="coerce").to_numpy()
    x = pd.to_numeric(table["x_ref"], errors="coerce").to_numpy()
    bad = ~(np.isfinite(t) & np.isfinite(x))
    if bad.any():
        raise ReferenceError(
            f"{path}: non-numeric or non-finite values in rows {np.flatnonzero(bad)[:5] + 2}"
        )
    expected = np.arange(len(t)) * sample_period
    if len(t) < 4 or not np.allclose(t, expected, atol=1e-9 + 1e-6 * sample_period):
        raise ReferenceError(
            f"{path}: column 't' must start at 0 and step by sample_period = {sample_period} s "
            "(at least 4 samples)"
        )
    return x


@dataclass(frozen=True)
class ReferenceGrid:
    """The reference on the position-loop grid.

    Attributes
    ----------
    period : float
        Position-loop period, s.
    position, velocity, acceleration : numpy.ndarray
        Carriage reference in m, m/s, m/s^2 at t = k * period.
    """

    period: float
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @property
    def time(self) -> np.ndarray:
        """Sample times, s (index times period)."""
        return np.arange(len(self.position)) * self.period

    @property
    def duration(self) -> float:
        """Length of the reference, s."""
        return (len(self.position) - 1) * self.period


def check_periods(sample_period: float, loop_period: float) -> int:
    """Samples of the position loop (period ``loop_period``, s) per reference sample.

    Raises
    ------
    ReferenceError
        Unless ``sample_period`` (s) is a whole multiple (>= 1) of ``loop_period``.
    """
    ratio = sample_period / loop_period
    if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-9:
        raise ReferenceError(
            f"reference sample_period {sample_period} s must be a whole multiple of the "
            f"position-loop period {loop_period} s"
        )
    return round(ratio)


def interpolate(samples: np.ndarray, sample_period: float, loop_period: float) -> ReferenceGrid:
    """Cubic-spline interpolation of 4-ms samples onto the position-loop grid.

    A grid made before from the same inputs is read back from the per-user cache (the same
    numbers, without SciPy).

    Parameters
    ----------
    samples
        Positions, m, at t = k * sample_period.
    sample_period
        Interpolator input period, s (4 ms on the paper's CNC).
    loop_period
        Position-loop period, s (250 us); must divide sample_period.
    """
    ratio = check_periods(sample_period, loop_period)
    key = _grid_key(samples, sample_period, loop_period)
    stored = _load_grid(key)
    if stored is not None:
        return ReferenceGrid(loop_period, *stored)
    from scipy.interpolate import CubicSpline  # heavy: only for a reference not seen before

    spline = CubicSpline(np.arange(len(samples)) * sample_period, samples, bc_type="clamped")
    t = np.arange((len(samples) - 1) * ratio + 1) * loop_period
    grid = ReferenceGrid(loop_period, spline(t), spline(t, 1), spline(t, 2))
    _store_grid(key, grid.position, grid.velocity, grid.acceleration)
    return grid


def _grid_key(samples: np.ndarray, sample_period: float, loop_period: float) -> str:
    """The digest of a grid's inputs: samples (m), periods (s), this source file (the
    interpolation's code) and the versions of SciPy and numpy."""
    digest = hashlib.sha256(np.ascontiguousarray(samples, dtype=np.float64).tobytes())
    versions = (installed_version("scipy") or "", installed_version("numpy") or "")
    for part in (repr(sample_period), repr(loop_period), *versions):
        digest.update(part.encode())
    digest.update(Path(__file__).read_bytes())
    return digest.hexdigest()[:32]


def _grid_path(key: str) -> Path:
    """Where the grid of ``key`` is kept in the per-user cache."""
    return cache_dir() / "references" / f"{key}.npy"


def _load_grid(key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The stored position (m), velocity (m/s) and acceleration (m/s^2) of ``key``, or None."""
    try:
        stored = np.load(_grid_path(key))
    except (OSError, ValueError):  # not stored yet, or unreadable: interpolate again
        return None
    position, velocity, acceleration = (np.array(row) for row in stored)
    return position, velocity, acceleration


def _store_grid(
    key: str, position: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray
) -> None:
    """Store a grid under ``key`` (atomically)."""
    path = _grid_path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as file:
            np.save(file, np.stack([position, velocity, acceleration]))
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


STANDSTILL = 0.05  # s of zero reference speed that make a dwell
START_WINDOW = 0.05  # s after a dwell in which the start's acceleration counts
MARGIN = 0.2  # a held-out figure counts as outside above (1 + MARGIN) x the tuned largest
STILL_SPEED = 1e-9  # m/s: below this the reference stands still

LABELS = {
    "speed": ("speed", 1e3, "mm/s"),
    "acceleration": ("acceleration", 1.0, "m/s^2"),
    "reversal_acceleration": ("reversal while moving at", 1.0, "m/s^2"),
    "start_acceleration": ("start from a dwell at", 1.0, "m/s^2"),
}


@dataclass(frozen=True)
class MotionEnvelope:
    """Largest speed (m/s) and accelerations (m/s^2) of a reference, by regime."""

    speed: float
    acceleration: float
    reversal_acceleration: float
    start_acceleration: float


def envelope_of(reference: ReferenceGrid) -> MotionEnvelope:
    """The motion envelope of a reference on the position-loop grid.

    A sign change of v_ref across fewer than STANDSTILL of still samples (a zero crossing may
    fall on a sample) is a reversal while moving; motion after at least STANDSTILL of them (or
    from the start) is a start from a dwell.
    """
    v, a = reference.velocity, np.abs(reference.acceleration)
    dwell = int(round(STANDSTILL / reference.period))
    window = max(1, int(round(START_WINDOW / reference.period)))
    moving = np.flatnonzero(np.abs(v) > STILL_SPEED)
    reversal = start = 0.0
    if len(moving):
        if moving[0] >= dwell:
            start = float(a[max(moving[0] - 1, 0) : moving[0] + window].max())
        for i, j in zip(moving[:-1], moving[1:], strict=True):
            if j - i - 1 >= dwell:
                start = max(start, float(a[j - 1 : j + window].max()))
            elif np.sign(v[i]) != np.sign(v[j]):
                reversal = max(reversal, float(a[i : j + 1].max()))
    return MotionEnvelope(float(np.max(np.abs(v))), float(a.max()), reversal, start)


def outside(held: MotionEnvelope, tuned: list[MotionEnvelope]) -> list[str]:
    """What of ``held`` lies beyond every tuned envelope by more than MARGIN, in words.

    Returns
    -------
    list of str
        One line per figure, e.g. ``start from a dwell at 0.57 m/s^2 (tuned: up to 0.2)``;
        empty when the held-out motion stays within the tuning's.
    """
    found = []
    for field in fields(MotionEnvelope):
        value = getattr(held, field.name)
        covered = max(getattr(t, field.name) for t in tuned)
        if value > (1.0 + MARGIN) * covered:
            label, scale, unit = LABELS[field.name]
            found.append(f"{label} {value * scale:.3g} {unit} (tuned: up to {covered * scale:.3g})")
    return found
