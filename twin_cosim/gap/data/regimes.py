"""Motion regimes of a reference trajectory and the share of the residual energy in each.

Each sample of the reference (speed ``v_ref`` in m/s, acceleration ``a_ref`` in m/s^2, carriage
side) gets one regime; the thresholds are the fields of :class:`RegimeSettings`.

- *moving*: |v_ref| > ``v_still`` over a stretch of one direction that travels more than
  :data:`MIN_TRAVEL`; the direction of motion is the sign of v_ref while moving. The reference
  interpolated to the loop grid undershoots where a move starts or ends (a cubic spline through
  4 ms samples: tens of um/s the other way over a fraction of a micrometre); those wiggles are
  no motion, or each start from a dwell would follow a motion the other way and be taken for a
  reversal, and no sample would ever be a breakaway.
- A *motion start* is a moving sample whose direction differs from the sample before (which is
  either at standstill or moving the other way). The previous direction of motion is the direction
  of the last moving sample before it, however long the dwell in between.
- *reversal*: |t - t_s| <= ``window`` around a motion start at t_s whose direction is opposite to
  the previous direction of motion: the reference speed passes through zero, or leaves a dwell in
  the direction it did not arrive from.
- *breakaway*: t_s <= t <= t_s + ``window`` after a motion start in the same direction as the
  previous motion, or after the first motion of the record: the drive leaves standstill.
- *standstill*: not moving.
- *acceleration*: moving and |a_ref| > ``a_min``.
- *constant_velocity*: the remaining samples.

Precedence where these overlap: reversal > breakaway > standstill > acceleration >
constant_velocity. A record that starts in motion has no motion start at its first sample: the
motion began earlier, its direction is the previous direction for the next start.

A *stroke* (:func:`strokes`) is a stretch of one direction of motion whose position covers more
than ``MIN_TRAVEL`` (of a direction signal given by the caller, e.g. from the measured motion).

**Open-loop runs** (:func:`classify_open_loop`): a plant driven by a measured signal (a torque
stepped from level to level) has no reference; its regimes follow its measured speed through
each stretch where the drive holds one value. Until the speed settles (its running mean over
``OPEN_LOOP_SMOOTHING`` stays within ``SETTLED_SHARE`` of the change it makes in the stretch, the
stretch's final speed being its mean over the last ``FINAL_SHARE``) a stretch is a *run-up from
rest* when it starts at standstill, labelled ``breakaway`` (the axis leaves standstill), or the
response *after a step*, labelled ``acceleration``; then *steady speed*, ``constant_velocity``;
samples where the measured speed is at most ``STILL_SHARE`` of its largest magnitude are
``standstill``.

Energy shares of a residual r (m or A) per regime: ``time_share`` = fraction of the samples,
``energy_share`` = fraction of sum r^2, ``enrichment`` = energy_share / time_share (0 for a regime
that does not occur).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

REGIMES = ("standstill", "breakaway", "acceleration", "constant_velocity", "reversal")
STANDSTILL, BREAKAWAY, ACCELERATION, CONSTANT_VELOCITY, REVERSAL = range(len(REGIMES))

_TIME_TOLERANCE = 1e-9  # s, absorbs rounding of grid times at the window edges
MIN_TRAVEL = 1e-6  # m: a stretch of one direction that covers less is no stroke
# Open-loop regimes: the running mean of the measured speed, the band it settles in (a share of
# the change of speed in a stretch of the drive), the stretch's end whose mean is its final
# speed, and what counts as standing still (a share of the largest speed).
OPEN_LOOP_SMOOTHING = 0.05  # s
SETTLED_SHARE = 0.05
FINAL_SHARE = 0.2
STILL_SHARE = 1e-3


@dataclass(frozen=True)
class RegimeSettings:
    """Thresholds of the regime classification.

    Attributes
    ----------
    v_still : float
        Speed at or below which the reference stands still, m/s (carriage).
    a_min : float
        Acceleration above which a moving sample accelerates, m/s^2.
    window : float
        Half width of a reversal window and length of a breakaway window, s.
    """

    v_still: float = 1e-5
    a_min: float = 1e-3
    window: float = 0.05


def _motion_starts(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the motion starts and whether each is a reversal.

    ``direction`` holds -1, 0 (standstill) or +1 per sample.
    """
    before = np.concatenate(([0], direction[:-1]))
    starts = np.flatnonzero((direction != 0) & (direction != before))
    previous = np.concatenate(([0], direction[starts[:-1]]))
    if direction[0] != 0:  # the motion began before the record: not a start
        previous, starts = previous[1:], starts[1:]
    return starts, (previous != 0) & (previous != direction[starts])


def classify_regimes(
    t: np.ndarray,
    v_ref: np.ndarray,
    a_ref: np.ndarray,
    settings: RegimeSettings = RegimeSettings(),
) -> np.ndarray:
    """Label each sample with the index of its regime in :data:`REGIMES`.

    Parameters
    ----------
    t : np.ndarray
        Sample times, s, increasing.
    v_ref : np.ndarray
        Reference speed of the carriage, m/s.
    a_ref : np.ndarray
        Reference acceleration of the carriage, m/s^2.
    settings : RegimeSettings
        Thresholds; see the module docstring for the definitions.

    Returns
    -------
    np.ndarray
        Integer regime codes, one per sample.

    Raises
    ------
    ValueError
        When the arrays are not 1-D of one length or ``t`` does not increase.
    """
    t, v_ref, a_ref = (np.asarray(a, dtype=float) for a in (t, v_ref, a_ref))
    if t.ndim != 1 or v_ref.shape != t.shape or a_ref.shape != t.shape:
        raise ValueError("t, v_ref and a_ref must be 1-D arrays of one length")
    if np.any(np.diff(t) <= 0.0):
        raise ValueError("t must increase strictly")
    moving = _moving(t, v_ref, settings.v_still)
    labels = np.full(t.shape, CONSTANT_VELOCITY, dtype=int)
    labels[moving & (np.abs(a_ref) > settings.a_min)] = ACCELERATION
    labels[~moving] = STANDSTILL
    starts, reversal = _motion_starts(np.where(moving, np.sign(v_ref), 0.0))
    for start in starts[~reversal]:
        labels[_window(t, t[start], t[start] + settings.window)] = BREAKAWAY
    for start in starts[reversal]:
        labels[_window(t, t[start] - settings.window, t[start] + settings.window)] = REVERSAL
    return labels


def drive_steps(drive: np.ndarray) -> np.ndarray:
    """Indices where an open-loop run's drive signal takes a new value, its first sample
    included: the starts of its stretches of one level."""
    drive = np.asarray(drive)
    return np.concatenate(([0], np.flatnonzero(np.diff(drive) != 0) + 1))


def classify_open_loop(t: np.ndarray, speed: np.ndarray, drive: np.ndarray) -> np.ndarray:
    """Label each sample of an open-loop run with the index of its regime in :data:`REGIMES`
    (see the module docstring: run-up from rest as ``breakaway``, after a step as
    ``acceleration``, steady speed as ``constant_velocity``).

    Parameters
    ----------
    t : np.ndarray
        Sample times, s, increasing and regular.
    speed : np.ndarray
        Measured motor speed, rad/s.
    drive : np.ndarray
        The drive signal (any unit): its changes start the stretches.

    Raises
    ------
    ValueError
        When the arrays are not 1-D of one length, or hold fewer than two samples.
    """
    from scipy.ndimage import uniform_filter1d  # here: the replay workers import this module

    t, speed, drive = (np.asarray(a, dtype=float) for a in (t, speed, drive))
    if t.ndim != 1 or speed.shape != t.shape or drive.shape != t.shape or len(t) < 2:
        raise ValueError("t, speed and drive must be 1-D arrays of one length, 2 or more")
    dt = float(np.median(np.diff(t)))
    width = max(int(round(OPEN_LOOP_SMOOTHING / dt)), 1)
    smooth = uniform_filter1d(speed, width, mode="nearest")
    labels = np.full(t.shape, CONSTANT_VELOCITY, dtype=int)
    edges = np.append(drive_steps(drive), len(t))
    still = STILL_SHARE * float(np.max(np.abs(speed)))
    for start, stop in zip(edges[:-1], edges[1:], strict=True):
        final = float(np.mean(speed[stop - max(int(FINAL_SHARE * (stop - start)), 1) : stop]))
        change = abs(final - smooth[start])
        outside = np.flatnonzero(np.abs(smooth[start:stop] - final) > SETTLED_SHARE * change)
        settled = start + (int(outside[-1]) + 1 if len(outside) else 0)
        labels[start:settled] = BREAKAWAY if abs(speed[start]) <= still else ACCELERATION
    labels[np.abs(smooth) <= still] = STANDSTILL
    return labels


def _moving(t: np.ndarray, v_ref: np.ndarray, v_still: float) -> np.ndarray:
    """Whether each sample moves: above ``v_still`` (m/s) in a stretch of one direction whose
    travel (the integral of |v_ref| over t, m) exceeds :data:`MIN_TRAVEL`."""
    direction = np.where(np.abs(v_ref) > v_still, np.sign(v_ref), 0.0)
    step = np.abs(v_ref) * np.gradient(t)  # m travelled per sample
    moving = direction != 0
    for first, stop, _ in _runs(direction):
        if step[first:stop].sum() <= MIN_TRAVEL:
            moving[first:stop] = False
    return moving


def _runs(direction: np.ndarray) -> list[tuple[int, int, int]]:
    """[start, stop) index ranges of one non-zero direction, with that direction."""
    changes = np.flatnonzero(np.diff(direction)) + 1
    firsts, stops = np.concatenate(([0], changes)), np.concatenate((changes, [len(direction)]))
    return [
        (int(a), int(b), int(direction[a]))
        for a, b in zip(firsts, stops, strict=True)
        if direction[a] != 0
    ]


def _window(t: np.ndarray, t_from: float, t_to: float) -> slice:
    """Index slice of the samples with t_from <= t <= t_to (times in s)."""
    first = np.searchsorted(t, t_from - _TIME_TOLERANCE, side="left")
    stop = np.searchsorted(t, t_to + _TIME_TOLERANCE, side="right")
    return slice(int(first), int(stop))


def energy_shares(residual: np.ndarray, labels: np.ndarray) -> dict[str, dict[str, float]]:
    """Share of time and of residual energy per regime, and their ratio.

    Parameters
    ----------
    residual : np.ndarray
        Residual measured - simulated per sample (m or A).
    labels : np.ndarray
        Regime codes from :func:`classify_regimes`.

    Returns
    -------
    dict[str, dict[str, float]]
        For each name in :data:`REGIMES`: ``time_share``, ``energy_share`` and ``enrichment``
        (dimensionless; all 0 for an absent regime, energy shares 0 for a zero residual).

    Raises
    ------
    ValueError
        When the arrays are empty, differ in shape or the residual is not finite.
    """
    residual, labels = np.asarray(residual, dtype=float), np.asarray(labels)
    if residual.size == 0 or residual.shape != labels.shape:
        raise ValueError("residual and labels must be non-empty arrays of one shape")
    if not np.all(np.isfinite(residual)):
        raise ValueError("the residual holds non-finite values")
    energy = residual**2
    total = float(energy.sum())
    shares = {}
    for code, name in enumerate(REGIMES):
        inside = labels == code
        time_share = float(inside.mean())
        energy_share = float(energy[inside].sum()) / total if total > 0.0 else 0.0
        enrichment = energy_share / time_share if time_share > 0.0 else 0.0
        shares[name] = {
            "time_share": time_share,
            "energy_share": energy_share,
            "enrichment": enrichment,
        }
    return shares


def strokes(direction: np.ndarray, position: np.ndarray) -> list[tuple[int, int, int]]:
    """Strokes: [start, stop) index ranges of one direction of motion whose position covers
    more than :data:`MIN_TRAVEL`, with that direction.

    Parameters
    ----------
    direction : np.ndarray
        -1, 0 (standstill) or +1 per sample.
    position : np.ndarray
        Carriage position per sample, m.
    """
    return [
        (a, b, d) for a, b, d in _runs(np.asarray(direction)) if np.ptp(position[a:b]) > MIN_TRAVEL
    ]


def segments(labels: np.ndarray, code: int) -> list[tuple[int, int]]:
    """Contiguous [start, stop) index ranges where ``labels`` equals ``code``."""
    inside = np.concatenate(([False], np.asarray(labels) == code, [False]))
    edges = np.flatnonzero(np.diff(inside.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]
