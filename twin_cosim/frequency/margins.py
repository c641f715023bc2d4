"""Stability margins of an open loop L: from measured frequency-response data, or of a system.

- gain margin: -|L| in dB where the phase crosses -180 degrees (L real and negative);
- phase margin: 180 degrees + the phase of L where |L| crosses 0 dB; its frequency is the
  crossover;
- of several crossings, the one nearest to instability counts, as python-control's
  ``stability_margins`` chooses: the smallest |gain margin| in dB, the smallest |phase margin|;
- bandwidth: where the closed loop T = L / (1 + L) first falls below -3 dB;
- resonance peak: the largest |T|, dB, and its frequency;
- peak sensitivity: the largest |S| = |1 / (1 + L)|, dB, and its frequency.

A closed loop or a sensitivity measured as such gives its open loop, L = T / (1 - T) or
L = 1 / S - 1 (:func:`open_loop_of`), so that every measured response of a loop has the same
figures.

From measured data (:func:`margins_of_data`) the crossings are interpolated between the
measured lines, linearly in log-frequency (magnitude in dB, unwrapped phase; at most one phase
crossing between neighbouring lines); only crossings within the measured band are found. With
the coherence of the lines, a figure counts only where the data can be trusted: every line up
to the first at or above the frequency it is read at must have a coherence at or above the
floor (:data:`COHERENCE_FLOOR`). Below the floor the response is not the loop's (friction
sticks, the backlash opens, noise), and a crossing may hide there or be a false one, so a figure
read above an incoherent line is withheld: None in its field, and listed in ``withheld`` with
the value read, its frequency and the lowest coherence below it. Of a linearised loop
(:func:`margins_of_system`) python-control finds the crossings on its response over a dense grid
up to the Nyquist frequency; the closed-loop figures come from the same grid.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from twin_cosim.frequency.linear import Discrete

DENSE_POINTS = 4000
COHERENCE_FLOOR = 0.9  # a figure read above a line of lower coherence is withheld


@dataclass(frozen=True)
class Margins:
    """The margins and closed-loop figures of one loop (None where there is no crossing, or
    where a measured figure is withheld).

    Attributes
    ----------
    gain_margin_db : float or None
        Gain margin, dB.
    phase_margin_deg : float or None
        Phase margin, degrees.
    crossover_hz : float or None
        Gain crossover (|L| = 1) of the phase margin, Hz.
    phase_crossover_hz : float or None
        Phase crossover (-180 degrees) of the gain margin, Hz.
    bandwidth_hz : float or None
        Closed-loop -3 dB bandwidth, Hz.
    peak_sensitivity_db : float or None
        Largest |1 / (1 + L)|, dB.
    peak_sensitivity_hz : float or None
        Where it lies, Hz.
    resonance_peak_db : float or None
        Largest |L / (1 + L)| of the closed loop, dB.
    resonance_peak_hz : float or None
        Where it lies, Hz.
    withheld : dict
        Measured figures read where the coherence is below the floor, by field name:
        ``value`` (as read), ``frequency_hz``, ``lowest_coherence`` (of the lines up to it),
        ``floor``.
    """

    gain_margin_db: float | None
    phase_margin_deg: float | None
    crossover_hz: float | None
    phase_crossover_hz: float | None
    bandwidth_hz: float | None
    peak_sensitivity_db: float | None
    peak_sensitivity_hz: float | None = None
    resonance_peak_db: float | None = None
    resonance_peak_hz: float | None = None
    withheld: dict[str, dict[str, float]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def _interpolate(x0: float, x1: float, y0: float, y1: float, y: float) -> float:
    """x where the line through (x0, y0), (x1, y1) reaches y."""
    return x0 + (x1 - x0) * (y - y0) / (y1 - y0)


def _log_crossing(f: np.ndarray, values: np.ndarray, level: float, i: int) -> float:
    """Frequency (Hz) where ``values`` crosses ``level`` between lines i and i + 1."""
    return math.exp(
        _interpolate(math.log(f[i]), math.log(f[i + 1]), values[i], values[i + 1], level)
    )


def _at(f: np.ndarray, values: np.ndarray, at: float) -> float:
    """``values`` interpolated linearly in log-frequency at ``at`` (Hz)."""
    return float(np.interp(math.log(at), np.log(f), values))


def bandwidth_hz(frequency_hz: np.ndarray, loop: np.ndarray) -> float | None:
    """Where |L / (1 + L)| first falls below -3 dB, Hz (None when it never does)."""
    closed_db = 20 * np.log10(np.abs(loop / (1.0 + loop)))
    below = np.flatnonzero(closed_db < -3.0103)
    if len(below) == 0:
        return None
    i = int(below[0])
    if i == 0:
        return float(frequency_hz[0])
    return _log_crossing(frequency_hz, closed_db, -3.0103, i - 1)


def open_loop_of(kind: str, response: np.ndarray) -> np.ndarray:
    """The open loop L of a loop's response of ``kind``: open (L itself), closed
    (L = T / (1 - T)) or sensitivity (L = 1 / S - 1), complex."""
    if kind == "closed":
        return response / (1.0 - response)
    if kind == "sensitivity":
        return 1.0 / response - 1.0
    return response


def _crossings(f: np.ndarray, loop: np.ndarray) -> tuple[tuple, tuple]:
    """The gain and phase margins of the crossings nearest to instability, each (|margin|,
    margin, frequency) or (None, None, None)."""
    magnitude_db = 20 * np.log10(np.abs(loop))
    phase = np.degrees(np.unwrap(np.angle(loop)))
    gains = []  # (|gain margin dB|, gain margin dB, frequency)
    turn = np.floor((phase + 180.0) / 360.0)  # -180 + 360 turn is the last level at or below
    for i in np.flatnonzero(np.diff(turn) != 0):  # one level between neighbouring lines
        level = -180.0 + 360.0 * max(turn[i], turn[i + 1])
        at = _log_crossing(f, phase, level, int(i))
        margin = -_at(f, magnitude_db, at)
        gains.append((abs(margin), margin, at))
    if abs(np.angle(-loop[-1])) < 1e-9:  # real and negative at the last line (Nyquist)
        gains.append((abs(magnitude_db[-1]), -float(magnitude_db[-1]), float(f[-1])))
    phases = []  # (|phase margin|, phase margin, frequency)
    for i in np.flatnonzero(np.diff(np.sign(magnitude_db))):  # |L| crosses 1
        at = _log_crossing(f, magnitude_db, 0.0, int(i))
        margin = (_at(f, phase, at) % 360.0) - 180.0
        phases.append((abs(margin), margin, at))
    return min(gains, default=(None, None, None)), min(phases, default=(None, None, None))


def phase_margin_of(frequency_hz: np.ndarray, loop: np.ndarray) -> float | None:
    """The phase margin (deg) alone of an open loop given at increasing frequencies, as
    :func:`margins_of_data` reads it (None without a gain crossover)."""
    return _crossings(np.asarray(frequency_hz, dtype=np.float64), loop)[1][1]


def _peak(f: np.ndarray, values_db: np.ndarray) -> tuple[float, float]:
    """The largest value (dB) and its frequency (Hz)."""
    i = int(np.argmax(values_db))
    return float(values_db[i]), float(f[i])


def margins_of_data(
    frequency_hz: np.ndarray,
    loop: np.ndarray,
    coherence: np.ndarray | None = None,
    floor: float = COHERENCE_FLOOR,
) -> Margins:
    """The margins of an open loop given at increasing frequencies (Hz), complex values.

    With ``coherence`` (gamma^2 per line) a figure read at or above an incoherent line (below
    ``floor``) is withheld (module docstring).
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    gain, pm = _crossings(f, loop)
    sensitivity_db, sensitivity_hz = _peak(f, -20 * np.log10(np.abs(1.0 + loop)))
    resonance_db, resonance_hz = _peak(f, 20 * np.log10(np.abs(loop / (1.0 + loop))))
    bandwidth = bandwidth_hz(f, loop)
    read = {  # field: (value, the frequency it is read at)
        "gain_margin_db": (gain[1], gain[2]),
        "phase_margin_deg": (pm[1], pm[2]),
        "bandwidth_hz": (bandwidth, bandwidth),
        "peak_sensitivity_db": (sensitivity_db, sensitivity_hz),
        "resonance_peak_db": (resonance_db, resonance_hz),
    }
    withheld = {} if coherence is None else _untrusted(f, coherence, floor, read)
    value = {name: None if name in withheld else v for name, (v, _) in read.items()}
    return Margins(
        gain_margin_db=value["gain_margin_db"],
        phase_margin_deg=value["phase_margin_deg"],
        crossover_hz=None if "phase_margin_deg" in withheld else pm[2],
        phase_crossover_hz=None if "gain_margin_db" in withheld else gain[2],
        bandwidth_hz=value["bandwidth_hz"],
        peak_sensitivity_db=value["peak_sensitivity_db"],
        peak_sensitivity_hz=None if "peak_sensitivity_db" in withheld else sensitivity_hz,
        resonance_peak_db=value["resonance_peak_db"],
        resonance_peak_hz=None if "resonance_peak_db" in withheld else resonance_hz,
        withheld=withheld,
    )


def _untrusted(
    f: np.ndarray,
    coherence: np.ndarray,
    floor: float,
    read: dict[str, tuple[float | None, float | None]],
) -> dict[str, dict[str, float]]:
    """The figures read at or above the first line whose coherence is below ``floor``."""
    incoherent = np.flatnonzero(np.asarray(coherence) < floor)
    if not len(incoherent):
        return {}
    first = int(incoherent[0])
    withheld = {}
    for name, (value, at) in read.items():
        if value is None or at is None:
            continue
        line = int(np.searchsorted(f, at * (1 - 1e-12)))  # the first line at or above it
        if line >= first:
            withheld[name] = {
                "value": float(value),
                "frequency_hz": float(at),
                "lowest_coherence": float(np.min(coherence[: min(line, len(f) - 1) + 1])),
                "floor": floor,
            }
    return withheld


def dense_grid(low_hz: float, nyquist_hz: float, points: int = DENSE_POINTS) -> np.ndarray:
    """Log-spaced frequencies from ``low_hz`` up to the Nyquist frequency itself, Hz."""
    return np.geomspace(low_hz, nyquist_hz, points)


def margins_of_system(system: Discrete, low_hz: float = 0.1) -> Margins:
    """The margins of a discrete open loop, its crossings found by python-control.

    python-control's ``stability_margins`` runs on the loop's response on a dense grid up to the
    Nyquist frequency (its polynomial method is numerically unreliable for these loops, with
    their double pole at z = 1). ``low_hz`` is the grid's lowest frequency, Hz.
    """
    grid = dense_grid(low_hz, 0.5 / system.dt)
    return margins_of_response(grid, system.siso(grid))


def margins_of_response(frequency_hz: np.ndarray, loop: np.ndarray) -> Margins:
    """The margins of a discrete open loop given on a dense grid up to its Nyquist frequency.

    python-control finds the crossings below the last frequency; the last one, the Nyquist
    frequency where a discrete loop is real, counts as a phase crossing when the loop is
    negative there.
    """
    import control

    grid = np.asarray(frequency_hz, dtype=np.float64)
    data = control.frd(loop[:-1], 2 * np.pi * grid[:-1])
    gm, pm, _, w_gm, w_pm, _ = control.stability_margins(data, returnall=True)
    gains = [
        (abs(math.log(g)), 20 * math.log10(g), w / (2 * math.pi))
        for g, w in zip(gm, w_gm, strict=True)
    ]
    if loop[-1].real < 0:
        nyquist = abs(loop[-1])
        gains.append((abs(math.log(nyquist)), -20 * math.log10(nyquist), float(grid[-1])))
    phases = [(abs(p), float(p), w / (2 * math.pi)) for p, w in zip(pm, w_pm, strict=True)]
    gain = min(gains, default=(None, None, None))
    phase = min(phases, default=(None, None, None))
    sensitivity_db, sensitivity_hz = _peak(grid, -20 * np.log10(np.abs(1.0 + loop)))
    resonance_db, resonance_hz = _peak(grid, 20 * np.log10(np.abs(loop / (1.0 + loop))))
    return Margins(
        gain_margin_db=None if gain[1] is None else float(gain[1]),
        phase_margin_deg=phase[1],
        crossover_hz=None if phase[2] is None else float(phase[2]),
        phase_crossover_hz=None if gain[2] is None else float(gain[2]),
        bandwidth_hz=bandwidth_hz(grid, loop),
        peak_sensitivity_db=sensitivity_db,
        peak_sensitivity_hz=sensitivity_hz,
        resonance_peak_db=resonance_db,
        resonance_peak_hz=resonance_hz,
    )
