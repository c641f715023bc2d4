"""The ``optimize`` section of a scenario: bounds, objective window, control-effort cap, penalty;
the current-filter parameters tuned with the six.

Every key is optional; the defaults make ``twin optimize scenarios/reference1.yaml --method ce``
work as it is::

    optimize:
      bounds:                      # physical [low, high] per tuned parameter
        Kp_pos: [20.0, 150.0]      # 1/s
        Kp_vel: [0.05, 1.5]        # A/(rad/s)
        Ki_vel: [0.0, 0.03]        # A/(rad/s) per speed-loop sample
        PP2: [0.0, 5.0]            # rad/s
        PP3: [0.001, 0.1]          # s
        f_H: [0.0, 0.5]            # rad/s
        filter1.frequency_hz: [80.0, 160.0]   # optional: a current filter's parameter tuned
                                              # too (filter dimensions, below)
      window: null                 # [t0, tF] s of the objective; null: the scenario's window
      iau_cap: 1.05                # IAU at most 1.05 x the Fine-Tune set's IAU; null: no cap
      abort_error_um: 1000.0       # a run whose |error| exceeds this is stopped: unstable
      penalty_um: 1.0e+6           # violation: penalty + E_pk; failure: 2 x penalty
      methods: {ce: {q: 0.1}}      # per-method setting overrides (see docs/optimizers.md)

The objective is eq. (12): minimise E_pk (um) over the window, subject to the IAU cap. A
candidate is the six of eq. (7), then any filter dimensions.

**Filter dimensions**: current-filter parameters tuned with the six, extra dimensions named in
``optimize.bounds``.

A bound named ``filter<k>.<parameter>`` tunes that parameter of the k-th section (from 1) of the
scenario's ``controller.settings.filters``, e.g.::

    optimize:
      bounds:
        filter1.frequency_hz: [80.0, 160.0]     # Hz
        filter1.depth_db: [-30.0, -3.0]         # dB

Such dimensions follow the six of eq. (7), in the order the bounds name them; without them a
campaign tunes exactly the six (its records and results unchanged). A candidate's filter values
replace those of the section in every case's settings.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin_cosim import current_filters
from twin_cosim.controller import TUNED_NAMES, ControllerSettings, TunedParameters
from twin_cosim.current_filters import CurrentFilter
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario
from twin_cosim.schema import Checker

NAME = re.compile(r"filter(\d+)\.(\w+)")


@dataclasses.dataclass(frozen=True)
class FilterDimension:
    """One tuned filter parameter.

    Attributes
    ----------
    name : str
        ``filter<k>.<parameter>``.
    section : int
        Index of the section in the settings' filters (from 0).
    parameter : str
        A field of that section (frequency_hz, bandwidth_hz, depth_db, damping).
    """

    name: str
    section: int
    parameter: str


def parse_dimension(name: str, filters: Sequence[CurrentFilter]) -> FilterDimension | None:
    """The filter dimension a bound's name stands for; None when it names none.

    Raises
    ------
    ValueError
        When the name has the form but no such section or parameter exists.
    """
    match = NAME.fullmatch(name)
    if match is None:
        return None
    index, parameter = int(match.group(1)), match.group(2)
    if not 1 <= index <= len(filters):
        raise ValueError(
            f"{name}: controller.settings.filters has {len(filters)} section(s); "
            "filter<k> counts them from 1"
        )
    section = filters[index - 1]
    fields = [f.name for f in dataclasses.fields(section)]
    if parameter not in fields:
        raise ValueError(f"{name}: a {section.kind} has the parameters {fields}")
    return FilterDimension(name, index - 1, parameter)


def check_bounds(
    dimension: FilterDimension, bounds: tuple[float, float], settings: ControllerSettings
) -> None:
    """ValueError unless the section is valid at both bounds (as the filters check it)."""
    for value in bounds:
        with_filters(settings, [dimension], np.array([value]))


def with_filters(
    settings: ControllerSettings, dimensions: Sequence[FilterDimension], values: np.ndarray
) -> ControllerSettings:
    """``settings`` with the dimensions' sections set to ``values``.

    Raises
    ------
    ValueError
        When a value makes an invalid section (e.g. a frequency above the Nyquist frequency).
    """
    if not dimensions:
        return settings
    filters = list(settings.filters)
    for dimension, value in zip(dimensions, values, strict=True):
        if dimension.section >= len(filters):
            raise ValueError(
                f"{dimension.name}: these settings have only {len(filters)} filter section(s)"
            )
        filters[dimension.section] = dataclasses.replace(
            filters[dimension.section], **{dimension.parameter: float(value)}
        )
    current_filters.check_below_nyquist(filters, settings.speed_period)
    return dataclasses.replace(settings, filters=tuple(filters))


def start_values(settings: ControllerSettings, dimensions: Sequence[FilterDimension]) -> np.ndarray:
    """The dimensions' values in ``settings`` (the campaign's start)."""
    return np.array([getattr(settings.filters[d.section], d.parameter) for d in dimensions])


DEFAULT_BOUNDS: dict[str, tuple[float, float]] = {
    "Kp_pos": (20.0, 150.0),
    "Kp_vel": (0.05, 1.5),
    "Ki_vel": (0.0, 0.03),
    "PP2": (0.0, 5.0),
    "PP3": (0.001, 0.1),
    "f_H": (0.0, 0.5),
}
KEYS = {"bounds", "window", "iau_cap", "abort_error_um", "penalty_um", "methods"}


@dataclass(frozen=True)
class OptimizeConfig:
    """Checked ``optimize`` section.

    Attributes
    ----------
    lower, upper : numpy.ndarray
        Physical bounds of [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] (units of the controller),
        then of the filter dimensions.
    window : tuple
        Objective window (t0, tF) in s; tF None: to the end.
    iau_cap : float or None
        Allowed IAU relative to the Fine-Tune set's IAU.
    abort_error_um : float
        Error (um) beyond which a run is stopped and scored as unstable.
    penalty_um : float
        Penalty (um) of a constraint violation; a failure scores twice this.
    methods : dict
        Per-method setting overrides.
    tuned_names : tuple of str
        Name of each tuned controller parameter, in the order of the bounds (the six; a
        machine's campaign names them per axis, ``X.Kp_pos``).
    filters : tuple of FilterDimension
        Current-filter parameters tuned after those (none: the tuned parameters alone).
    """

    lower: np.ndarray
    upper: np.ndarray
    window: tuple[float, float | None]
    iau_cap: float | None = 1.05
    abort_error_um: float = 1000.0
    penalty_um: float = 1.0e6
    methods: dict[str, dict[str, Any]] = field(default_factory=dict)
    tuned_names: tuple[str, ...] = TUNED_NAMES
    filters: tuple[FilterDimension, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        """The tuned dimensions: the controller parameters, then the filter dimensions."""
        return self.tuned_names + tuple(d.name for d in self.filters)

    def parameters(self, x: np.ndarray) -> dict[str, float]:
        """A candidate (physical units) by dimension name."""
        return {name: float(v) for name, v in zip(self.names, x, strict=True)}

    def candidate(
        self, x: np.ndarray, settings: ControllerSettings
    ) -> tuple[TunedParameters, ControllerSettings]:
        """The six and the settings (its filter dimensions applied) of a candidate.

        Raises
        ------
        ValueError
            When the controller refuses the values.
        """
        tuned = TunedParameters.from_array(np.asarray(x)[: len(TUNED_NAMES)])
        return tuned, with_filters(settings, self.filters, np.asarray(x)[len(TUNED_NAMES) :])

    def start(self, tuned: TunedParameters, settings: ControllerSettings) -> np.ndarray:
        """The candidate of a set: its six, then its filter values."""
        return np.concatenate([tuned.as_array(), start_values(settings, self.filters)])

    def to_unit(self, x: np.ndarray) -> np.ndarray:
        """Physical parameters -> normalised [0, 1] box."""
        return (np.asarray(x, dtype=np.float64) - self.lower) / (self.upper - self.lower)

    def from_unit(self, u: np.ndarray) -> np.ndarray:
        """Normalised [0, 1] box -> physical parameters."""
        return self.lower + np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0) * (
            self.upper - self.lower
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form (for the campaign's record)."""
        return {
            "bounds": {
                n: [float(lo), float(hi)]
                for n, lo, hi in zip(self.names, self.lower, self.upper, strict=True)
            },
            "window": list(self.window),
            "iau_cap": self.iau_cap,
            "abort_error_um": self.abort_error_um,
            "penalty_um": self.penalty_um,
            "methods": self.methods,
        }


def load_config(scenario: Scenario) -> OptimizeConfig:
    """Check the scenario's ``optimize`` section and fill in the defaults.

    Raises
    ------
    ScenarioError
        Naming the file and key on unknown keys, bad bounds or values.
    """
    check = Checker(scenario.source)
    data = check.mapping(scenario.optimize, "optimize", KEYS)
    bounds = dict(DEFAULT_BOUNDS)
    raw_bounds = data.get("bounds") or {}
    if not isinstance(raw_bounds, dict):
        raise check.fail("optimize.bounds", f"a mapping of {list(TUNED_NAMES)}")
    filters: list[FilterDimension] = []
    for name, pair in raw_bounds.items():
        try:
            dimension = parse_dimension(str(name), scenario.settings.filters)
        except ValueError as exc:
            raise check.error(f"{check.source}: optimize.bounds.{exc}") from None
        if name not in bounds and dimension is None:
            raise check.fail(
                "optimize.bounds",
                f"{list(TUNED_NAMES)} or filter<k>.<parameter>; unknown parameter {name!r}",
            )
        if not isinstance(pair, list) or len(pair) != 2:
            raise check.fail(f"optimize.bounds.{name}", "[low, high]", pair)
        low = check.number(pair[0], f"optimize.bounds.{name}[0]")
        high = check.number(pair[1], f"optimize.bounds.{name}[1]")
        if not low < high:
            raise check.fail(f"optimize.bounds.{name}", "low < high", pair)
        if dimension is not None:
            try:
                check_bounds(dimension, (low, high), scenario.settings)
            except ValueError as exc:
                raise check.error(f"{check.source}: optimize.bounds.{name}: {exc}") from None
            filters.append(dimension)
        bounds[name] = (low, high)
    names = TUNED_NAMES + tuple(d.name for d in filters)
    lower = np.array([bounds[n][0] for n in names])
    upper = np.array([bounds[n][1] for n in names])
    for name, low in zip(TUNED_NAMES, lower[: len(TUNED_NAMES)], strict=True):
        positive_only = name in ("Kp_pos", "Kp_vel", "PP3")
        if low < 0 or (positive_only and low <= 0):
            raise check.fail(
                f"optimize.bounds.{name}",
                f"a lower bound {'> 0' if positive_only else '>= 0'}; lower bound {low} allows "
                "invalid values",
            )
    window = data.get("window")
    if window is None:
        window = scenario.metrics_window
    else:
        if not isinstance(window, list) or len(window) != 2:
            raise check.fail("optimize.window", "[t0, tF] in s", window)
        window = (
            check.number(window[0], "optimize.window[0]"),
            None
            if window[1] is None
            else check.number(window[1], "optimize.window[1]", positive=True),
        )
    iau_cap = data.get("iau_cap", 1.05)
    iau_cap = None if iau_cap is None else check.number(iau_cap, "optimize.iau_cap", positive=True)
    methods = data.get("methods") or {}
    if not isinstance(methods, dict) or not all(isinstance(v, dict) for v in methods.values()):
        raise check.fail("optimize.methods", "a mapping method -> settings")
    return OptimizeConfig(
        lower=lower,
        upper=upper,
        window=window,
        iau_cap=iau_cap,
        abort_error_um=check.number(
            data.get("abort_error_um", 1000.0), "optimize.abort_error_um", positive=True
        ),
        penalty_um=check.number(
            data.get("penalty_um", 1.0e6), "optimize.penalty_um", positive=True
        ),
        methods=methods,
        filters=tuple(filters),
    )


def within_bounds(config: OptimizeConfig, x: np.ndarray) -> bool:
    """Whether a candidate (physical units, every dimension) lies inside the bounds."""
    return bool(np.all((x >= config.lower) & (x <= config.upper)))


@dataclass(frozen=True)
class UncertaintySet:
    """Plant variations a robust campaign tunes against (and a prediction's interval spans).

    Attributes
    ----------
    tolerance : float
        Largest relative change of each uncertain parameter without a range (0.03: +/- 3 %).
    samples : int
        Plant samples per scenario; the first is the nominal (calibrated) plant, the others
        draw each factor uniformly from its range, or from [1 - tolerance, 1 + tolerance].
    seed : int
        Seed of the draws.
    parameters : tuple of str
        The uncertain FMU parameters.
    ranges : dict
        Per parameter, the range (low, high) of its relative factor: a plant file's interval
        over the nominal value (:func:`relative_ranges`).
    """

    tolerance: float
    samples: int
    seed: int
    parameters: tuple[str, ...]
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)

    def factors(self) -> list[dict[str, float]]:
        """Relative factors per sample (the first sample: none, the nominal plant)."""
        rng = np.random.default_rng(self.seed)
        draws: list[dict[str, float]] = [{}]
        for _ in range(self.samples - 1):
            draw = {}
            for n in self.parameters:
                if n in self.ranges:
                    draw[n] = float(rng.uniform(*self.ranges[n]))
                else:
                    draw[n] = float(1.0 + rng.uniform(-self.tolerance, self.tolerance))
            draws.append(draw)
        return draws


def relative_ranges(
    intervals: dict[str, tuple[float, float]], nominal: dict[str, float]
) -> dict[str, tuple[float, float]]:
    """A plant file's intervals (SI units) as ranges of relative factors on the ``nominal``
    values; a parameter whose nominal value is 0 has no relative range and is left out."""
    ranges = {}
    for name, (low, high) in intervals.items():
        value = nominal.get(name, 0.0)
        if value != 0.0:
            ranges[name] = tuple(sorted((low / value, high / value)))
    return ranges


def uncertain_parameters(model: str, calibrated: dict[str, float]) -> tuple[str, ...]:
    """Default uncertain parameters: the model's calibrated ones and the non-zero real values of
    a plant parameter file (noise harmonics excepted)."""
    card = plant_model(model)
    variables = card.parameters
    names = list(card.calibrated)
    for name, value in calibrated.items():
        real = variables[name].type == "Real"
        if real and value != 0.0 and not name.startswith("noise_") and name not in names:
            names.append(name)
    return tuple(names)


def check_uncertainty(
    tolerance: float, samples: int, names: tuple[str, str] = ("--tolerance", "--samples")
) -> None:
    """ValueError naming the option (or key) unless 0 <= tolerance < 1 and samples >= 1."""
    if isinstance(samples, bool) or not isinstance(samples, int) or samples < 1:
        raise ValueError(f"{names[1]}: expected an integer >= 1, got {samples!r}")
    if not (isinstance(tolerance, (int, float)) and 0.0 <= tolerance < 1.0):
        raise ValueError(f"{names[0]}: expected a relative tolerance in [0, 1), got {tolerance!r}")
