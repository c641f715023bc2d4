"""Current-setpoint filters: second-order notch and low-pass sections after the speed controller.

A drive filters the current (torque) setpoint, the speed controller's output plus the
feedforward, through a chain of second-order sections, each set as drives parametrise it:

- **notch** (band-stop): blocking frequency f_n [Hz], bandwidth B [Hz], depth [dB]::

      N(s) = (s^2 + 2 zeta_z w_n s + w_n^2) / (s^2 + 2 zeta_p w_n s + w_n^2)
      w_n = 2 pi f_n,   zeta_p = B / (2 f_n),   zeta_z = zeta_p 10^(depth / 20)

  |N(j w_n)| = zeta_z / zeta_p is the depth; B is the -3 dB width of the full-depth notch
  (zeta_z = 0), and about that of a deep one.
- **low-pass**: frequency f_c [Hz], damping zeta (0.7071: Butterworth)::

      L(s) = w_c^2 / (s^2 + 2 zeta w_c s + w_c^2),   w_c = 2 pi f_c

Discrete-time form, at the speed-loop period T: the bilinear (Tustin) transform prewarped at the
section's frequency w_0 (w_n or w_c), s = K (1 - z^-1) / (1 + z^-1) with K = w_0 / tan(w_0 T / 2),
so that the discrete response at f_0 equals the continuous one (the notch blocks exactly f_n).
Each section H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2) runs in direct form II
transposed (two states z1, z2, zero at the start)::

    y  = b0 u + z1
    z1 = b1 u - a1 y + z2
    z2 = b2 u - a2 y

:func:`discrete_response` is the response of exactly these coefficients at z = exp(j w T);
:func:`continuous_response` the analytic response of the prototype.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import MISSING, asdict, dataclass, fields
from typing import Any

import numpy as np

BUTTERWORTH = 1.0 / math.sqrt(2.0)
COEFFICIENTS_PER_SECTION = 5  # b0, b1, b2, a1, a2
STATES_PER_SECTION = 2  # z1, z2


@dataclass(frozen=True)
class Notch:
    """A second-order notch on the current setpoint.

    Attributes
    ----------
    frequency_hz : float
        Blocking frequency f_n, Hz.
    bandwidth_hz : float
        Bandwidth B, Hz (-3 dB width of the full-depth notch): zeta_p = B / (2 f_n).
    depth_db : float
        Gain at f_n, dB (<= 0; -20 dB passes a tenth of the setpoint at f_n).
    """

    frequency_hz: float
    bandwidth_hz: float
    depth_db: float

    kind = "notch"

    def __post_init__(self) -> None:
        _check_positive(self, "frequency_hz", "bandwidth_hz")
        if not math.isfinite(self.depth_db) or self.depth_db > 0.0:
            raise ValueError(f"notch depth_db must be finite and <= 0 dB, got {self.depth_db}")

    def prototype(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Continuous numerator and denominator (s^2, s, 1 coefficients)."""
        w = 2.0 * math.pi * self.frequency_hz
        zeta_p = self.bandwidth_hz / (2.0 * self.frequency_hz)
        zeta_z = zeta_p * 10.0 ** (self.depth_db / 20.0)
        return (1.0, 2.0 * zeta_z * w, w * w), (1.0, 2.0 * zeta_p * w, w * w)


@dataclass(frozen=True)
class LowPass:
    """A second-order low-pass on the current setpoint.

    Attributes
    ----------
    frequency_hz : float
        Natural frequency f_c, Hz.
    damping : float
        Damping ratio zeta, 1 (0.7071: Butterworth, -3 dB at f_c).
    """

    frequency_hz: float
    damping: float = BUTTERWORTH

    kind = "lowpass"

    def __post_init__(self) -> None:
        _check_positive(self, "frequency_hz", "damping")

    def prototype(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Continuous numerator and denominator (s^2, s, 1 coefficients)."""
        w = 2.0 * math.pi * self.frequency_hz
        return (0.0, 0.0, w * w), (1.0, 2.0 * self.damping * w, w * w)


CurrentFilter = Notch | LowPass
KINDS: dict[str, type[Notch] | type[LowPass]] = {"notch": Notch, "lowpass": LowPass}


def _check_positive(section: CurrentFilter, *names: str) -> None:
    for name in names:
        value = getattr(section, name)
        if isinstance(value, bool) or not math.isfinite(value) or value <= 0.0:
            raise ValueError(f"{section.kind} {name} must be a finite number > 0, got {value!r}")


def check_below_nyquist(filters: Sequence[CurrentFilter], period: float) -> None:
    """ValueError naming the filter whose frequency is not below the Nyquist frequency.

    ``period`` is the speed-loop period, s (the filters run at it).
    """
    nyquist = 0.5 / period
    for index, section in enumerate(filters, start=1):
        if section.frequency_hz >= nyquist:
            raise ValueError(
                f"filter {index} ({section.kind}): frequency_hz {section.frequency_hz:g} Hz must "
                f"be below the speed loop's Nyquist frequency {nyquist:g} Hz"
            )


def continuous_response(section: CurrentFilter, frequency_hz: np.ndarray) -> np.ndarray:
    """The prototype's analytic response at ``frequency_hz`` (Hz), complex, 1."""
    (n2, n1, n0), (d2, d1, d0) = section.prototype()
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
    return (n2 * s**2 + n1 * s + n0) / (d2 * s**2 + d1 * s + d0)


def coefficients(section: CurrentFilter, period: float) -> np.ndarray:
    """[b0, b1, b2, a1, a2] of the Tustin form prewarped at the section's frequency.

    ``period`` is the sample period, s.
    """
    (n2, n1, n0), (d2, d1, d0) = section.prototype()
    w = 2.0 * math.pi * section.frequency_hz
    k = w / math.tan(w * period / 2.0)
    b = np.array([n2 * k * k + n1 * k + n0, 2.0 * (n0 - n2 * k * k), n2 * k * k - n1 * k + n0])
    a = np.array([d2 * k * k + d1 * k + d0, 2.0 * (d0 - d2 * k * k), d2 * k * k - d1 * k + d0])
    return np.concatenate([b / a[0], a[1:] / a[0]])


def discrete_response(
    section: CurrentFilter, frequency_hz: np.ndarray, period: float
) -> np.ndarray:
    """The discrete section's response at z = exp(j 2 pi f T), complex, 1."""
    b0, b1, b2, a1, a2 = coefficients(section, period)
    z1 = np.exp(-2j * np.pi * np.asarray(frequency_hz, dtype=np.float64) * period)
    return (b0 + b1 * z1 + b2 * z1**2) / (1.0 + a1 * z1 + a2 * z1**2)


def chain_response(
    filters: Sequence[CurrentFilter], frequency_hz: np.ndarray, period: float
) -> np.ndarray:
    """The discrete chain's response (the product of its sections'), complex, 1."""
    response = np.ones(np.shape(frequency_hz), dtype=np.complex128)
    for section in filters:
        response = response * discrete_response(section, frequency_hz, period)
    return response


def as_dict(section: CurrentFilter) -> dict[str, Any]:
    """The section as a scenario writes it: ``type`` and its parameters."""
    return {"type": section.kind, **asdict(section)}


def from_dict(data: dict[str, Any]) -> CurrentFilter:
    """A section from ``{type: notch|lowpass, ...parameters}``; ValueError names what is wrong."""
    kind = data.get("type")
    if kind not in KINDS:
        raise ValueError(f"filter type: expected one of {sorted(KINDS)}, got {kind!r}")
    cls = KINDS[kind]
    known = {f.name: f for f in fields(cls)}
    unknown = sorted(set(data) - set(known) - {"type"})
    if unknown:
        raise ValueError(f"{kind}: unknown key(s) {unknown}; allowed: {sorted(known)}")
    missing = sorted(n for n, f in known.items() if n not in data and f.default is MISSING)
    if missing:
        raise ValueError(f"{kind}: missing {missing}")
    values = {}
    for name in set(known) & set(data):
        value = data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{kind} {name}: expected a number, got {value!r}")
        values[name] = float(value)
    return cls(**values)
