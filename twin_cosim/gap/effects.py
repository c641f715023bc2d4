"""The library of unmodelled effects the diagnosis can fit, each a block of the plant FMU.

Every hypothesis has 1 to 4 parameters in physical units and maps them to FMU parameters on
top of the twin's nominal values (documented per effect in ``docs/gap.md`` and in
``models/drive2mass/README.md``). Periodic effects take their order from the data (the dominant
peak of the residual's order spectrum, see :mod:`twin_cosim.gap.diagnosis`); their amplitude and
phase are fitted as a cosine and a sine coefficient so that the fit has no phase wrapping.

Fitting kinds: ``continuous`` (scipy least_squares), ``scan`` (a few discrete values, each
replayed, given by the hypothesis' own ``scan``): dead time in controller samples, encoder
resolution estimated from the data.

One registry, :data:`LIBRARIES`, holds the hypotheses of each plant model; adding an effect means
its FMU block, one :class:`Hypothesis` entry here and its test.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

Overrides = dict[str, float]
Context = Mapping[str, float]

# Orders of periodic effects when the data show none (the diagnosis takes them from the
# residual's order spectra; twin synth uses them when an effect is given without ``order``).
DEFAULT_CONTEXT: dict[str, float] = {"motor_order": 6.0, "screw_order": 1.0}


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


@dataclass(frozen=True)
class Hypothesis:
    """A candidate unmodelled effect.

    Attributes
    ----------
    name : str
        Name shared with the FMU block (see ``twin synth --effect``).
    parameters : tuple of HypothesisParameter
        The fitted parameters.
    to_plant : callable
        (values, nominal plant parameters, context) -> FMU parameter overrides.
    kind : str
        ``continuous`` or ``scan``.
    signature : str
        Where the effect shows (regime, signal, domain).
    relative_size : callable or None
        For a change of a calibrated parameter: (values, nominal) -> size of the change relative
        to the nominal value, compared with the calibration tolerance; None for the others.
    scan : callable or None
        For a ``scan`` hypothesis: (hypothesis, context) -> the values to try.
    periodic_in : str or None
        ``"motor"`` or ``"screw"`` for an effect periodic in that angle, whose order the
        diagnosis reads from the residual (context key ``motor_order`` / ``screw_order``).
    """

    name: str
    parameters: tuple[HypothesisParameter, ...]
    to_plant: Callable[[np.ndarray, Mapping[str, float], Context], Overrides]
    kind: str
    signature: str
    relative_size: Callable[[np.ndarray, Mapping[str, float]], float] | None = None
    scan: Callable[[Hypothesis, Context], list[np.ndarray]] | None = None
    periodic_in: str | None = None

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Fit coordinates in [0, 1] -> physical values."""
        return np.array([p.from_unit(float(x)) for p, x in zip(self.parameters, u, strict=True)])

    def initial_unit(self) -> np.ndarray:
        """Fit coordinates of the start values."""
        return np.array([p.to_unit(p.initial) for p in self.parameters])

    def named(self, values: np.ndarray) -> dict[str, float]:
        """Fitted values by parameter name."""
        return {p.name: float(v) for p, v in zip(self.parameters, values, strict=True)}


def _amplitude_phase(cos_part: float, sin_part: float) -> tuple[float, float]:
    """a cos(u) + b sin(u) = A cos(u + phi): returns (A, phi)."""
    return math.hypot(cos_part, sin_part), math.atan2(-sin_part, cos_part)


def _stribeck(v, nominal, context) -> Overrides:
    return {"stribeck_friction": v[0], "stribeck_speed": v[1]}


def _coulomb(v, nominal, context) -> Overrides:
    return {"coulomb_friction": nominal["coulomb_friction"] + v[0]}


def _asymmetric(v, nominal, context) -> Overrides:
    return {"coulomb_asymmetry": v[0]}


def _position_friction(v, nominal, context) -> Overrides:
    amplitude, phase = _amplitude_phase(v[0], v[1])
    return {
        "position_friction_amplitude": amplitude,
        "position_friction_phase": phase,
        "position_friction_order": context["screw_order"],
    }


def _pitch_error(v, nominal, context) -> Overrides:
    amplitude, phase = _amplitude_phase(v[1], v[2])
    # e sin(u + p) with the fitted a cos(u) + b sin(u) = A cos(u + phi): p = phi + pi/2.
    return {
        "pitch_error_linear": v[0],
        "pitch_error_amplitude_1": amplitude,
        "pitch_error_phase_1": phase + math.pi / 2,
    }


def _torque_ripple(v, nominal, context) -> Overrides:
    amplitude, phase = _amplitude_phase(v[0], v[1])
    return {
        "ripple_amplitude": amplitude,
        "ripple_phase": phase + math.pi / 2,
        "ripple_order": context["motor_order"],
    }


def _current_lag(v, nominal, context) -> Overrides:
    return {"current_time_constant": v[0]}


def _dead_time(v, nominal, context) -> Overrides:
    return {"dead_time_steps": float(round(v[0]))}


def _scan_dead_time(hypothesis: Hypothesis, context: Context) -> list[np.ndarray]:
    """Whole numbers of samples between the bounds, the nominal one left out."""
    low, high = int(hypothesis.parameters[0].lower), int(hypothesis.parameters[0].upper)
    nominal = int(context.get("dead_time_steps", 0))
    return [np.array([float(n)]) for n in range(low, high + 1) if n != nominal]


def _scan_resolution(hypothesis: Hypothesis, context: Context) -> list[np.ndarray]:
    """The encoder resolution read off the measured position, when it lies on a grid."""
    resolution = context.get("position_resolution", 0.0)
    return [np.array([resolution])] if resolution > 0 else []


def _quantization(v, nominal, context) -> Overrides:
    return {"position_resolution": v[0]}


def _backlash(v, nominal, context) -> Overrides:
    return {"backlash": nominal["backlash"] + v[0]}


def _inertia(v, nominal, context) -> Overrides:
    scale = 1.0 + v[0]  # same coupling stiffness: f_1 = sqrt(K / J_L) / (2 pi) moves with J_L
    return {
        "motor_inertia": nominal["motor_inertia"] * scale,
        "load_inertia": nominal["load_inertia"] * scale,
        "resonance_frequency": nominal["resonance_frequency"] / math.sqrt(scale),
    }


def _stiffness(v, nominal, context) -> Overrides:
    return {"resonance_frequency": nominal["resonance_frequency"] * math.sqrt(1.0 + v[0])}


P = HypothesisParameter
LIBRARY: tuple[Hypothesis, ...] = (
    Hypothesis(
        "stribeck",
        (
            P("stribeck_friction", "N.m", 0.1, 0.0, 2.0),
            P("stribeck_speed", "rad/s", 0.5, 0.05, 2.0, log=True),
        ),
        _stribeck,
        "continuous",
        "breakaway and reversal spikes; position and current; time domain, local at v = 0",
    ),
    Hypothesis(
        "coulomb_change",
        (P("delta_coulomb", "N.m", 0.0, -0.6, 2.0),),
        _coulomb,
        "continuous",
        "every motion and reversal; current offset of constant sign per direction",
        lambda v, nominal: abs(v[0]) / nominal["coulomb_friction"],
    ),
    Hypothesis(
        "asymmetric_friction",
        (P("coulomb_asymmetry", "N.m", 0.0, -0.6, 0.6),),
        _asymmetric,
        "continuous",
        "constant velocity and reversals; current residual of one sign in both directions",
    ),
    Hypothesis(
        "position_friction",
        (P("cos_part", "1", 0.0, -0.9, 0.9), P("sin_part", "1", 0.0, -0.9, 0.9)),
        _position_friction,
        "continuous",
        "constant velocity; current; a fixed order of the screw angle at every speed",
        periodic_in="screw",
    ),
    Hypothesis(
        "pitch_error",
        (
            P("pitch_error_linear", "1", 0.0, -1e-3, 1e-3),
            P("cos_part", "m", 0.0, -1e-4, 1e-4),
            P("sin_part", "m", 0.0, -1e-4, 1e-4),
        ),
        _pitch_error,
        "continuous",
        "constant velocity; position; low orders of the screw angle, growing with speed",
    ),
    Hypothesis(
        "torque_ripple",
        (P("cos_part", "N.m", 0.0, -2.0, 2.0), P("sin_part", "N.m", 0.0, -2.0, 2.0)),
        _torque_ripple,
        "continuous",
        "constant velocity; current; a fixed order of the motor angle at every speed",
        periodic_in="motor",
    ),
    Hypothesis(
        "current_lag",
        (P("current_time_constant", "s", 2e-4, 0.0, 5e-3),),
        _current_lag,
        "continuous",
        "reversals and high jerk; phase of position and current",
    ),
    Hypothesis(
        "dead_time",
        (P("dead_time_steps", "1", 1.0, 1.0, 8.0),),
        _dead_time,
        "scan",
        "reversals and high jerk; phase of position and current",
        scan=_scan_dead_time,
    ),
    Hypothesis(
        "quantization",
        (P("position_resolution", "m", 0.0, 0.0, 1e-3),),
        _quantization,
        "scan",
        "standstill dither; high frequency; position",
        scan=_scan_resolution,
    ),
    Hypothesis(
        "backlash_change",
        (P("delta_backlash", "m", 0.0, -12e-6, 60e-6),),
        _backlash,
        "continuous",
        "reversals only; a position step of about the change, independent of speed",
        lambda v, nominal: abs(v[0]) / nominal["backlash"] if nominal["backlash"] else math.inf,
    ),
    Hypothesis(
        "inertia_change",
        (P("relative_change", "1", 0.0, -0.5, 1.0),),
        _inertia,
        "continuous",
        "accelerations; current proportional to acceleration",
        lambda v, nominal: abs(v[0]),
    ),
    Hypothesis(
        "stiffness_change",
        (P("relative_change", "1", 0.0, -0.8, 3.0),),
        _stiffness,
        "continuous",
        "accelerations and reversals; resonance ringing shifts in frequency",
        lambda v, nominal: abs(math.sqrt(1.0 + v[0]) - 1.0),  # relative change of f_1
    ),
)


def _emps_mass(v, nominal, context) -> Overrides:
    return {"mass": nominal["mass"] * (1.0 + v[0])}


def _emps_viscous(v, nominal, context) -> Overrides:
    return {"viscous_friction": nominal["viscous_friction"] + v[0]}


def _emps_asymmetric(v, nominal, context) -> Overrides:
    return {"coulomb_asymmetry": v[0], "viscous_asymmetry": v[1]}


def _emps_offset(v, nominal, context) -> Overrides:
    return {"force_offset": nominal["force_offset"] + v[0]}


def _emps_compliance(v, nominal, context) -> Overrides:
    return {"second_mass": nominal["mass"] * v[0], "coupling_frequency": v[1]}


def _emps_dead_time(v, nominal, context) -> Overrides:
    return {"dead_time_steps": float(round(v[0]))}


# The EMPS benchmark's linear axis (models/emps): forces in N, speeds in m/s, a rigid one-mass
# nominal model with a one-sample drive delay.
EMPS_LIBRARY: tuple[Hypothesis, ...] = (
    Hypothesis(
        "stribeck",
        (
            P("stribeck_friction", "N", 2.0, 0.0, 20.0),
            P("stribeck_speed", "m/s", 2e-3, 1e-4, 0.05, log=True),
        ),
        _stribeck,
        "continuous",
        "breakaway and reversal spikes of the force; local at v = 0",
    ),
    Hypothesis(
        "coulomb_change",
        (P("delta_coulomb", "N", 0.0, -15.0, 20.0),),
        _coulomb,
        "continuous",
        "force offset of constant sign per direction of motion",
        lambda v, nominal: abs(v[0]) / nominal["coulomb_friction"],
    ),
    Hypothesis(
        "asymmetric_friction",
        (
            P("coulomb_asymmetry", "N", 0.0, -10.0, 10.0),
            P("viscous_asymmetry", "N.s/m", 0.0, -100.0, 100.0),
        ),
        _emps_asymmetric,
        "continuous",
        "constant velocity; force residual that differs between the two directions",
    ),
    Hypothesis(
        "viscous_change",
        (P("delta_viscous", "N.s/m", 0.0, -150.0, 300.0),),
        _emps_viscous,
        "continuous",
        "constant velocity; force residual proportional to speed",
        lambda v, nominal: abs(v[0]) / nominal["viscous_friction"],
    ),
    Hypothesis(
        "offset_change",
        (P("delta_offset", "N", 0.0, -10.0, 10.0),),
        _emps_offset,
        "continuous",
        "everywhere, standstill included; a constant force residual",
    ),
    Hypothesis(
        "inertia_change",
        (P("relative_change", "1", 0.0, -0.5, 1.0),),
        _emps_mass,
        "continuous",
        "accelerations; force proportional to acceleration",
        lambda v, nominal: abs(v[0]),
    ),
    Hypothesis(
        "compliance",
        (
            P("mass_fraction", "1", 0.2, 0.02, 0.9),
            P("coupling_frequency", "Hz", 30.0, 5.0, 200.0, log=True),
        ),
        _emps_compliance,
        "continuous",
        "accelerations and jerks; ringing at the coupling frequency in force and position",
    ),
    Hypothesis(
        "torque_ripple",
        (P("cos_part", "N", 0.0, -10.0, 10.0), P("sin_part", "N", 0.0, -10.0, 10.0)),
        _torque_ripple,
        "continuous",
        "constant velocity; force; a fixed order of the motor angle at every speed",
        periodic_in="motor",
    ),
    Hypothesis(
        "dead_time",
        (P("dead_time_steps", "1", 2.0, 0.0, 4.0),),
        _emps_dead_time,
        "scan",
        "phase of force and position at every change of acceleration",
        scan=_scan_dead_time,
    ),
)
LIBRARIES: dict[str, tuple[Hypothesis, ...]] = {"drive2mass": LIBRARY, "emps": EMPS_LIBRARY}

# Parameters whose nominal values are only known to the calibration tolerance; their changes by
# that tolerance set the calibration floor of a diagnosis.
CALIBRATED: dict[str, tuple[str, ...]] = {
    "drive2mass": (
        "motor_inertia",
        "load_inertia",
        "resonance_frequency",
        "damping_ratio",
        "torque_constant",
        "coulomb_friction",
        "backlash",
    ),
    "emps": ("mass", "viscous_friction", "coulomb_friction", "force_offset", "drive_gain"),
}
BY_NAME: dict[str, Hypothesis] = {h.name: h for h in LIBRARY}


class UnknownModelError(ValueError):
    """No hypothesis library for a plant model."""


def library_for(model_identifier: str) -> tuple[Hypothesis, ...]:
    """The hypotheses of a plant model (its FMU's modelIdentifier).

    Raises
    ------
    UnknownModelError
        For a model without a library (the diagnosis cannot guess what another plant's
        effects are called).
    """
    if model_identifier not in LIBRARIES:
        raise UnknownModelError(
            f"no hypothesis library for plant model {model_identifier!r}; "
            f"libraries exist for {sorted(LIBRARIES)} (twin_cosim/gap/effects.py)"
        )
    return LIBRARIES[model_identifier]


def scan_values(hypothesis: Hypothesis, context: Context) -> list[np.ndarray]:
    """Values a ``scan`` hypothesis tries."""
    if hypothesis.scan is None:
        raise ValueError(f"hypothesis {hypothesis.name!r} is not a scan")
    return hypothesis.scan(hypothesis, context)


def estimate_resolution(x: np.ndarray) -> float:
    """The grid step of a quantised position signal (m), 0.0 when the signal is not on a grid.

    The most common non-zero step between consecutive samples is taken as the resolution when
    every step is (within 1 %) a whole multiple of it.
    """
    steps = np.abs(np.diff(x))
    steps = steps[steps > 1e-15]
    if len(steps) < 10:
        return 0.0
    smallest = np.quantile(steps, 0.01)
    multiples = steps / smallest
    if np.all(np.abs(multiples - np.round(multiples)) < 0.01):
        return float(smallest)
    return 0.0
