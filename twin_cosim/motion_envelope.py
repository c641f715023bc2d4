"""The motion regimes a trajectory covers, and whether a held-out one leaves those of the tuning.

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

from dataclasses import dataclass, fields

import numpy as np

from twin_cosim.reference import ReferenceGrid

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
