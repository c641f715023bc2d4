"""Everything the Python side knows about a plant model, read from its folder in ``models/``.

A plant model is a folder ``models/<model>/`` with its C sources, its variable table
``variables.yaml`` (names, units, ranges, start values: the single source of the C header and of
``modelDescription.xml``) and its card ``card.yaml``:

- ``drive``: what the drive assumes about the plant (``travel_per_rad`` [m/rad], ``inertia``
  [kg.m2], ``torque_constant`` [N.m/A], ``friction_torque`` [N.m], ``speed_period`` [s]) as
  formulas of the plant parameters;
- ``motor_per_screw``: motor radians per screw radian (the screw angle of periodic effects);
- ``calibrated``: parameters known only to the calibration tolerance;
- ``effects``: the hypotheses of the gap diagnosis (:class:`Hypothesis`, below);
- ``linear`` (optional): for the frequency analysis (:mod:`twin_cosim.frequency`), the parameter
  values that switch the nonlinearities off (``nonlinear_off``) and the linear two-mass system
  (``two_mass``: :data:`TWO_MASS` as formulas of the parameters);
- ``constraints`` (optional): what the FMU refuses at initialisation although each parameter lies
  in its range (``{holds: FORMULA, says: TEXT}``: the formula of the parameters must be >= 0,
  e.g. ``coulomb_friction - abs(coulomb_asymmetry)``), so that such values are refused before
  any FMU runs (:meth:`PlantModel.broken_constraints`), naming the values.

:func:`plant_model` reads and checks both files once per process. Adding an effect to a model's
library touches its folder (the FMU block in ``model.c`` and ``variables.yaml``, its entry in
``card.yaml``, its README) and its test, nothing else.

**Effect hypotheses**: candidate unmodelled effects of a plant model, as its card declares them.

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

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_build.build import COMMON_DIR, DEFAULT_MODEL, MODELS_DIR, available_models
from fmu_build.variable_table import Variable, VariableTable, load_variable_table
from twin_cosim.card_expressions import Formula, FormulaError
from twin_cosim.schema import Checker, load_yaml

# What the drive assumes about the plant, each a formula of the plant parameters in the card.
DRIVE_FACTS = ("travel_per_rad", "inertia", "torque_constant", "friction_torque", "speed_period")
CARD_KEYS = {"model", "drive", "motor_per_screw", "calibrated", "effects", "linear", "constraints"}
CONSTRAINT_KEYS = {"holds", "says"}
# The linear two-mass system of a card's ``linear.two_mass``, motor-referred: J_M [kg.m2],
# J_L [kg.m2], coupling stiffness [N.m/rad] and damping [N.m.s/rad], viscous friction on the load
# [N.m.s/rad], torque constant [N.m/A], carriage travel per load radian at the scale [m/rad],
# current-loop lag [s] and dead time [s] of the current.
TWO_MASS = (
    "motor_inertia",
    "load_inertia",
    "stiffness",
    "damping",
    "viscous_friction",
    "torque_constant",
    "travel_per_rad",
    "current_lag",
    "dead_time",
)
EFFECT_KEYS = {"signature", "parameters", "sets", "relative_size", "scan", "periodic_in"}
PARAMETER_KEYS = {"name", "unit", "initial", "lower", "upper", "log"}
PERIODIC_ANGLES = {"motor": "motor_order", "screw": "screw_order"}
# Values the diagnosis reads from the data and hands to the formulas as context.NAME.
CONTEXT_NAMES = frozenset({"motor_order", "screw_order", "position_resolution", "dead_time_steps"})


class PlantModelError(ValueError):
    """A plant model is unknown, or its card is invalid (the message names the file and key)."""


@dataclass(frozen=True)
class Constraint:
    """A relation of parameter values the FMU needs: ``holds`` (a formula of the parameters)
    must be >= 0; ``says`` is the relation in words."""

    holds: Formula
    says: str


@dataclass(frozen=True)
class PlantModel:
    """One plant model: its variable table and its card.

    Attributes
    ----------
    name : str
        The model (a folder of ``models/``, the FMU's model identifier).
    table : VariableTable
        The variable table (``variables.yaml``).
    drive : dict
        Fact name (:data:`DRIVE_FACTS`) -> formula of the plant parameters.
    motor_per_screw : Formula
        Motor radians per screw radian, a formula of the plant parameters.
    calibrated : tuple of str
        Parameters known only to the calibration tolerance.
    hypotheses : tuple of Hypothesis
        The effect library of the gap diagnosis, in the card's order.
    nonlinear_off : dict
        Parameter values that switch every nonlinearity off; empty without a linear model.
    two_mass : dict
        Quantity (:data:`TWO_MASS`) -> formula of the parameters; empty without a linear model.
    constraints : tuple of Constraint
        Relations of parameter values the FMU refuses to start without.
    """

    name: str
    table: VariableTable
    drive: dict[str, Formula]
    motor_per_screw: Formula
    calibrated: tuple[str, ...]
    hypotheses: tuple[Hypothesis, ...]
    nonlinear_off: dict[str, float]
    two_mass: dict[str, Formula]
    constraints: tuple[Constraint, ...] = ()

    @property
    def parameters(self) -> dict[str, Variable]:
        """The model's parameters by name."""
        return {v.name: v for v in self.table.variables if v.causality == "parameter"}

    @property
    def variable_names(self) -> set[str]:
        """Names of all the model's variables."""
        return {v.name for v in self.table.variables}

    def require_parameters(self, names: Sequence[str], purpose: str) -> None:
        """PlantModelError naming ``purpose`` (what needs them) unless the model has all of
        the parameters ``names``."""
        missing = [name for name in names if name not in self.parameters]
        if missing:
            raise PlantModelError(
                f"{purpose} {list(names)}; plant model {self.name!r} has no {missing}"
            )

    def start_values(self) -> dict[str, float]:
        """Start values of the parameters (SI units of the variable table)."""
        return {name: float(v.start) for name, v in self.parameters.items() if v.start is not None}

    def drive_facts(self, parameters: Mapping[str, float] | None = None) -> dict[str, float]:
        """What the drive assumes about this plant (:data:`DRIVE_FACTS`, SI units).

        Parameters
        ----------
        parameters
            Plant parameter values on top of the start values.
        """
        values = {**self.start_values(), **(parameters or {})}
        return {name: formula(values) for name, formula in self.drive.items()}

    def linear_plant(self, parameters: Mapping[str, float] | None = None) -> dict[str, float]:
        """The linear two-mass system at these parameter values (:data:`TWO_MASS`, SI units).

        Raises
        ------
        PlantModelError
            When the model's card gives no linear model.
        """
        if not self.two_mass:
            raise PlantModelError(
                f"plant model {self.name!r}: its card (models/{self.name}/card.yaml) gives no "
                "linear model (linear.two_mass)"
            )
        values = {**self.start_values(), **(parameters or {})}
        return {name: formula(values) for name, formula in self.two_mass.items()}

    def screw_angle(self, motor_angle: Any, parameters: Mapping[str, float] | None = None) -> Any:
        """The screw angle (rad) of a motor angle (rad, a number or an array)."""
        values = {**self.start_values(), **(parameters or {})}
        return motor_angle / self.motor_per_screw(values)

    def broken_constraints(
        self, parameters: Mapping[str, float]
    ) -> list[tuple[str, tuple[str, ...]]]:
        """The constraints that ``parameters`` (on top of the start values) break: each in
        words with the values of its parameters, and those parameters; empty when the FMU can
        start with them."""
        values = {**self.start_values(), **parameters}
        broken = []
        for constraint in self.constraints:
            if not constraint.holds(values) >= 0.0:
                names = tuple(sorted(constraint.holds.uses & set(self.parameters)))
                used = ", ".join(
                    f"{name} = {values[name]:g} {self.parameters[name].unit}" for name in names
                )
                broken.append((f"{constraint.says} ({used})", names))
        return broken

    def hypothesis(self, name: str) -> Hypothesis:
        """The hypothesis of that name; PlantModelError lists the library when there is none."""
        for hypothesis in self.hypotheses:
            if hypothesis.name == name:
                return hypothesis
        raise PlantModelError(
            f"effect {name!r}: not an effect of plant model {self.name!r}; expected one of "
            f"{[h.name for h in self.hypotheses]}"
        )


def model_names() -> list[str]:
    """The project's plant models (folders of ``models/`` with a variable table)."""
    return available_models()


def plant_model(name: str = DEFAULT_MODEL) -> PlantModel:
    """The plant model ``models/<name>``, read and checked once per process.

    Raises
    ------
    PlantModelError
        For a model that is not one of ``models/``, or an invalid card.
    """
    return _read_plant_model(name)


@functools.cache
def _read_plant_model(name: str) -> PlantModel:
    """:func:`plant_model`, once per name (a call without the default name is the same key)."""
    if name not in available_models():
        raise PlantModelError(f"unknown plant model {name!r}: expected one of {available_models()}")
    table = load_variable_table(MODELS_DIR / name / "variables.yaml", COMMON_DIR / "units.yaml")
    return read_card(MODELS_DIR / name / "card.yaml", name, table)


def read_card(path: Path, name: str, table: VariableTable) -> PlantModel:
    """Read and check the card ``path`` of model ``name`` with its variable table.

    Raises
    ------
    PlantModelError
        Naming the file and the key on malformed YAML, unknown keys, a formula that uses a name
        or an operation it may not, a parameter that is not the model's, or bad bounds.
    """
    check = Checker(path, PlantModelError)
    data = check.mapping(load_yaml(path, PlantModelError), "(top level)", CARD_KEYS)
    if data.get("model") != name:
        raise check.fail("model", f"{name!r}, the model's folder", data.get("model"))
    parameters = tuple(v.name for v in table.variables if v.causality == "parameter")
    known = frozenset(parameters)
    drive = check.mapping(data.get("drive"), "drive", set(DRIVE_FACTS))
    missing = [fact for fact in DRIVE_FACTS if fact not in drive]
    if missing:
        raise check.fail("drive", f"a formula for each of {list(DRIVE_FACTS)}; missing {missing}")
    calibrated = check.names(data.get("calibrated", []), "calibrated")
    stray = sorted(set(calibrated) - known)
    if stray:
        raise check.fail("calibrated", "parameters of variables.yaml", stray)
    effects = check.mapping(data.get("effects"), "effects")
    nonlinear_off, two_mass = _linear(check, data.get("linear"), parameters)
    constraints = _constraints(check, data.get("constraints", []), parameters)
    return PlantModel(
        name=name,
        table=table,
        drive={k: _formula(check, f"drive.{k}", drive[k], parameters) for k in DRIVE_FACTS},
        motor_per_screw=_formula(
            check, "motor_per_screw", data.get("motor_per_screw", 1.0), parameters
        ),
        calibrated=calibrated,
        hypotheses=tuple(
            _hypothesis(check, f"effects.{key}", key, body, known) for key, body in effects.items()
        ),
        nonlinear_off=nonlinear_off,
        two_mass=two_mass,
        constraints=constraints,
    )


def _constraints(check: Checker, data: Any, parameters: tuple[str, ...]) -> tuple[Constraint, ...]:
    """The card's ``constraints``: a list of ``{holds: FORMULA, says: TEXT}``."""
    if not isinstance(data, list):
        raise check.fail("constraints", "a list of {holds: formula, says: text}", data)
    found = []
    for index, entry in enumerate(data):
        key = f"constraints[{index}]"
        entry = check.mapping(entry, key, CONSTRAINT_KEYS)
        found.append(
            Constraint(
                _formula(check, f"{key}.holds", entry.get("holds"), parameters),
                check.text(entry.get("says"), f"{key}.says"),
            )
        )
    return tuple(found)


def _linear(
    check: Checker, data: Any, parameters: tuple[str, ...]
) -> tuple[dict[str, float], dict[str, Formula]]:
    """The card's ``linear`` section: the values that switch nonlinearities off, the formulas."""
    if data is None:
        return {}, {}
    linear = check.mapping(data, "linear", {"nonlinear_off", "two_mass"})
    off = check.mapping(linear.get("nonlinear_off"), "linear.nonlinear_off")
    stray = sorted(set(off) - set(parameters))
    if stray:
        raise check.fail("linear.nonlinear_off", "parameters of variables.yaml", stray)
    formulas = check.mapping(linear.get("two_mass"), "linear.two_mass", set(TWO_MASS))
    missing = [name for name in TWO_MASS if name not in formulas]
    if missing:
        raise check.fail("linear.two_mass", f"a formula for each of {list(TWO_MASS)}", missing)
    return (
        {k: check.number(v, f"linear.nonlinear_off.{k}") for k, v in off.items()},
        {k: _formula(check, f"linear.two_mass.{k}", formulas[k], parameters) for k in TWO_MASS},
    )


def _formula(
    check: Checker,
    key: str,
    text: Any,
    names: tuple[str, ...],
    nominal: frozenset[str] = frozenset(),
    context: frozenset[str] = frozenset(),
) -> Formula:
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise check.fail(key, "a formula", text)
    try:
        return Formula(str(text), names, nominal, context)
    except FormulaError as exc:
        raise check.fail(key, "a formula of the names it may use", str(exc)) from None


def _parameter(check: Checker, key: str, entry: Any) -> HypothesisParameter:
    entry = check.mapping(entry, key, PARAMETER_KEYS)
    if "name" not in entry or "unit" not in entry:
        raise check.fail(key, "a name and a unit")
    numbers = {k: check.number(entry.get(k), f"{key}.{k}") for k in ("initial", "lower", "upper")}
    log = entry.get("log", False)
    if not isinstance(log, bool):
        raise check.fail(f"{key}.log", "true or false", log)
    if not numbers["lower"] <= numbers["initial"] <= numbers["upper"]:
        raise check.fail(key, "lower <= initial <= upper", numbers)
    if log and numbers["lower"] <= 0:
        raise check.fail(f"{key}.lower", "a number > 0 for a log-scaled parameter")
    return HypothesisParameter(
        check.text(entry["name"], f"{key}.name"),
        str(entry["unit"]),
        numbers["initial"],
        numbers["lower"],
        numbers["upper"],
        log,
    )


def _hypothesis(
    check: Checker, key: str, name: str, body: Any, known: frozenset[str]
) -> Hypothesis:
    body = check.mapping(body, key, EFFECT_KEYS)
    entries = body.get("parameters")
    if not isinstance(entries, list) or not 1 <= len(entries) <= 4:
        raise check.fail(f"{key}.parameters", "a list of 1 to 4 fitted parameters", entries)
    fitted = tuple(_parameter(check, f"{key}.parameters[{i}]", e) for i, e in enumerate(entries))
    names = tuple(p.name for p in fitted)
    sets = check.mapping(body.get("sets"), f"{key}.sets")
    if not sets or not set(sets) <= known:
        raise check.fail(
            f"{key}.sets", "FMU parameters of variables.yaml", sorted(set(sets) - known)
        )
    scan = body.get("scan")
    if scan is not None and scan not in SCANS:
        raise check.fail(f"{key}.scan", f"one of {sorted(SCANS)}", scan)
    periodic = body.get("periodic_in")
    if periodic is not None and periodic not in PERIODIC_ANGLES:
        raise check.fail(f"{key}.periodic_in", f"one of {sorted(PERIODIC_ANGLES)}", periodic)
    size = body.get("relative_size")
    return Hypothesis(
        name=name,
        parameters=fitted,
        sets={
            k: _formula(check, f"{key}.sets.{k}", v, names, known, CONTEXT_NAMES)
            for k, v in sets.items()
        },
        kind="continuous" if scan is None else "scan",
        signature=check.text(body.get("signature"), f"{key}.signature"),
        relative_size=None
        if size is None
        else RelativeSize(_formula(check, f"{key}.relative_size", size, names, known), names),
        scan=scan,
        periodic_in=periodic,
    )


def fmu_identity(fmu: Path | str) -> tuple[str, set[str], dict[str, float]]:
    """Model identifier, variable names and parameter start values of an FMU file (FMI 2.0 or
    3.0: the independent variable that FMI 3.0 declares, ``time``, is not among the names)."""
    from fmpy import read_model_description  # fmpy is heavy; only commands with an FMU file

    description = read_model_description(str(fmu), validate=False)
    identifier = (
        description.coSimulation.modelIdentifier
        if description.coSimulation is not None
        else description.modelName
    )
    starts = {
        v.name: float(v.start)
        for v in description.modelVariables
        if v.causality == "parameter" and v.start is not None
    }
    names = {v.name for v in description.modelVariables if v.causality != "independent"}
    return identifier, names, starts


def model_of(fmu: Path | str | None) -> str:
    """The plant model of an FMU file (its model identifier); the default model's when None.

    Raises
    ------
    PlantModelError
        When the FMU's model description cannot be read.
    """
    if fmu is None:
        return DEFAULT_MODEL
    try:
        return fmu_identity(fmu)[0]
    except Exception as exc:  # noqa: BLE001 - fmpy raises several kinds on a bad file
        raise PlantModelError(f"{fmu}: cannot read the FMU's model description: {exc}") from exc


def effects_table(name: str) -> str:
    """The model's effect library as a Markdown table (generated into its README)."""
    rows = [
        "| effect | fitted parameters [unit] (bounds) | FMU parameters it sets | where it shows |",
        "|---|---|---|---|",
    ]
    for h in plant_model(name).hypotheses:
        fitted = ", ".join(
            f"{p.name} [{p.unit}] ({p.lower:g} to {p.upper:g}{', log' if p.log else ''})"
            for p in h.parameters
        )
        fitted += f"; scanned: {SCAN_TEXT[h.scan]}" if h.scan else ""
        sets = ", ".join(f"`{k} = {f.text}`" for k, f in h.sets.items())
        rows.append(f"| {h.name} | {fitted} | {sets} | {h.signature} |")
    return "\n".join(rows) + "\n"


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
