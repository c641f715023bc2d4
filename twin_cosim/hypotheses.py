"""Effect hypotheses: candidate unmodelled effects of a plant model, as its card declares them.

Each hypothesis has 1 to 4 fitted parameters in physical units and formulas
(:mod:`twin_cosim.card_expressions`) that map them to FMU parameters on top of the twin's nominal
values. Periodic effects take their order from the data (``context.motor_order`` or
``context.screw_order``); their amplitude and phase are fitted as a cosine and a sine coefficient
so that the fit has no phase wrapping.

Fitting kinds: ``continuous`` (least squares over the bounds) or ``scan`` (a few discrete values,
each replayed): ``whole_numbers`` tries every whole number between the bounds but the nominal one
(``context.<parameter>``), ``from_data`` the value the diagnosis estimated from the data
(``context.<parameter>``, none when it is 0).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from twin_cosim.card_expressions import Formula

Overrides = dict[str, float]
Context = Mapping[str, float]


@dataclass(frozen=True)
class HypothesisParameter:
    """One fitted parameter: name, unit, start value and bounds (physical units).

    ``log``: the fit moves this parameter on a logarithmic scale (bounds must be > 0).
    """

    name: str
    unit: str
    initial: float
    lower: float
    upper: float
    log: bool = False

    def to_unit(self, value: float) -> float:
        """Physical value -> fit coordinate in [0, 1]."""
        if self.log:
            return math.log(value / self.lower) / math.log(self.upper / self.lower)
        return (value - self.lower) / (self.upper - self.lower)

    def from_unit(self, u: float) -> float:
        """Fit coordinate in [0, 1] -> physical value."""
        u = min(max(u, 0.0), 1.0)
        if self.log:
            return self.lower * (self.upper / self.lower) ** u
        return self.lower + u * (self.upper - self.lower)


def _scan_whole_numbers(hypothesis: Hypothesis, context: Context) -> list[np.ndarray]:
    """Whole numbers between the bounds, the nominal one left out."""
    parameter = hypothesis.parameters[0]
    low, high = int(parameter.lower), int(parameter.upper)
    nominal = int(context.get(parameter.name, 0))
    return [np.array([float(n)]) for n in range(low, high + 1) if n != nominal]


def _scan_from_data(hypothesis: Hypothesis, context: Context) -> list[np.ndarray]:
    """The value estimated from the data (e.g. an encoder resolution), when there is one."""
    value = context.get(hypothesis.parameters[0].name, 0.0)
    return [np.array([value])] if value > 0 else []


SCANS: dict[str, Callable[[Hypothesis, Context], list[np.ndarray]]] = {
    "whole_numbers": _scan_whole_numbers,
    "from_data": _scan_from_data,
}
SCAN_TEXT = {
    "whole_numbers": "every whole number between the bounds",
    "from_data": "the value read off the data",
}


class RelativeSize:
    """Size of a calibrated parameter's change relative to its nominal value (a formula)."""

    def __init__(self, formula: Formula, names: tuple[str, ...]) -> None:
        self.formula, self.names = formula, names

    def __call__(self, values: np.ndarray, nominal: Mapping[str, float]) -> float:
        """(fitted values, nominal plant parameters) -> relative size, 1."""
        return self.formula(dict(zip(self.names, values, strict=True)), nominal)


@dataclass(frozen=True)
class Hypothesis:
    """A candidate unmodelled effect.

    Attributes
    ----------
    name : str
        Name shared with the FMU block (see ``twin synth --effect``).
    parameters : tuple of HypothesisParameter
        The fitted parameters.
    sets : dict
        FMU parameter -> formula of the fitted values, ``nominal.*`` and ``context.*``.
    kind : str
        ``continuous`` or ``scan``.
    signature : str
        Where the effect shows (regime, signal, domain).
    relative_size : RelativeSize or None
        For a change of a calibrated parameter: (values, nominal) -> size of the change relative
        to the nominal value, compared with the calibration tolerance; None for the others.
    scan : str or None
        For a ``scan`` hypothesis: how it picks the values to try (a name of :data:`SCANS`).
    periodic_in : str or None
        ``"motor"`` or ``"screw"`` for an effect periodic in that angle, whose order the
        diagnosis reads from the residual (context key ``motor_order`` / ``screw_order``).
    """

    name: str
    parameters: tuple[HypothesisParameter, ...]
    sets: dict[str, Formula] = field(compare=False)
    kind: str
    signature: str
    relative_size: RelativeSize | None = field(default=None, compare=False)
    scan: str | None = None
    periodic_in: str | None = None

    def to_plant(
        self, values: np.ndarray, nominal: Mapping[str, float], context: Context
    ) -> Overrides:
        """FMU parameter overrides for fitted ``values`` on top of the ``nominal`` plant."""
        named = dict(zip((p.name for p in self.parameters), values, strict=True))
        return {name: float(f(named, nominal, context)) for name, f in self.sets.items()}

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Fit coordinates in [0, 1] -> physical values."""
        return np.array([p.from_unit(float(x)) for p, x in zip(self.parameters, u, strict=True)])

    def initial_unit(self) -> np.ndarray:
        """Fit coordinates of the start values."""
        return np.array([p.to_unit(p.initial) for p in self.parameters])

    def named(self, values: np.ndarray) -> dict[str, float]:
        """Fitted values by parameter name."""
        return {p.name: float(v) for p, v in zip(self.parameters, values, strict=True)}

    def scan_values(self, context: Context) -> list[np.ndarray]:
        """Values a ``scan`` hypothesis tries."""
        if self.scan is None:
            raise ValueError(f"hypothesis {self.name!r} is not a scan")
        return SCANS[self.scan](self, context)
