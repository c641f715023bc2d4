"""The drift tracker: the twin's baseline, the tracked effects' values per window by a fast
linear update, and the sequential tests that say when, and in which effect, the machine drifts.

**Sequential change detection** on per-window statistics: CUSUM tests whose false-alarm rate is
chosen from the stationary machine's window-to-window scatter.

Each statistic y_w (a tracked effect's value, the gap the effects leave) is standardised by the
mean and the spread of the baseline windows, z_w = (y_w - mean) / spread, and fed to Page's
CUSUM: S_w = max(0, S_{w-1} + z_w - k) upwards (and the same on -z_w downwards for a two-sided
test); the test alarms when S_w exceeds h. The change began after the last window at which S was
0.

The spread is the baseline windows' sample standard deviation raised to its upper confidence
bound (:data:`SPREAD_CONFIDENCE`: a spread measured on a few windows is too small as often as
too large, and a spread too small makes every window an alarm): with n baseline windows,
s sqrt((n - 1) / chi2_{n-1}(1 - confidence)). The allowance k is half a spread (the test most
sensitive to a shift of one spread), and h is set for an average run length without change
(ARL0, in windows) by Siegmund's approximation for normal increments,

    ARL0 = (exp(2 k b) - 2 k b - 1) / (2 k^2),  b = h + 1.166,

shared by the tests run side by side: each of m one-sided tests gets m times the design ARL0,
so that the first false alarm of any of them comes after the design ARL0 on average.

**Baseline.** The first ``baseline`` windows (at least :data:`MIN_BASELINE`) calibrate the twin,
unless the twin's plant parameters are given (``--plant-parameters``, the ``plant.yaml`` of
``twin diagnose``): the calibrated parameters of the plant model's card (relative changes, a
Gaussian prior of width the calibration tolerance, as the diagnosis' joint refits) are fitted
by :data:`CALIBRATION_ITERATIONS` Gauss-Newton steps (central differences: the inertias, the
Coulomb level and the torque constant scaled together leave the twin's runs unchanged, and
only the prior may place the fit along that direction; a one-sided difference's curvature
would) to the baseline windows' mean residual
(windows with one reference are averaged first: their replays are the same). The noise floors
come from the calibrated twin's residual at standstill (:func:`twin_cosim.gap.floors.noise.
noise_floors`).

**Fast update.** Once per calibration (and per reference: windows of another cycle get their
own), the twin replays the window's reference at the baseline and once per tracked parameter
moved by a step (:data:`STEP_SHARE` of its card range): the columns of J are the changes of
the normalised position and current, per unit of each parameter. A window's values are then
theta = J^+ r, r its normalised residual against the baseline twin: a least-squares update of
one replay and one matrix product, not a fit. What the update leaves, r - J theta, is the gap
the tracked effects do not explain.

**Tests.** The baseline windows' values set each statistic's mean and spread
(:class:`Cusum`, :func:`baseline_spread`), a spread never below the smallest change worth an
alarm (a thousandth of the nominal value of the calibrated parameter the effect changes, by
the card's ``relative_size``: the twin calibrated on the baseline windows is placed less
precisely than those windows measure a backlash); after them every window feeds a two-sided
CUSUM per tracked parameter and a one-sided one on the unexplained gap. An alarm names the statistic
that crossed (the effect; ``unexplained`` for the gap), since which window, at what rate, and
each test alarms once. Windows whose reference differs from that of baseline windows that all
shared one reference are checked (gap, values) but not tested: a cycle the baseline never saw.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.context import estimate_resolution
from twin_cosim.gap.data.residuals import joined
from twin_cosim.gap.floors.noise import Floors, noise_floors
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.plant import Plant
from twin_cosim.plant_model import Hypothesis, plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.runtime.opcua import Window
from twin_cosim.runtime.window_replay import (
    Gap,
    WindowCase,
    gap_of,
    replay,
    residuals,
    residuals_against,
    window_case,
)
from twin_cosim.scenario import Scenario

ALLOWANCE = 0.5  # k, in spreads
SPREAD_CONFIDENCE = 0.9  # the spread used is the upper bound of this one-sided confidence
SIEGMUND_OFFSET = 1.166


def siegmund_arl(h: float, k: float = ALLOWANCE) -> float:
    """Average run length (windows) of a one-sided CUSUM with threshold ``h`` and allowance
    ``k`` (both in spreads) on standard normal increments, by Siegmund's approximation."""
    b = 2.0 * k * (h + SIEGMUND_OFFSET)
    return (math.exp(b) - b - 1.0) / (2.0 * k * k)


def threshold_for(arl0: float, k: float = ALLOWANCE) -> float:
    """The threshold h (spreads) whose one-sided ARL0 (windows) is ``arl0``."""
    if arl0 <= 1.0:
        raise ValueError(f"an average run length must exceed 1 window, got {arl0}")
    low, high = 0.0, 100.0
    for _ in range(100):  # bisection: the ARL grows with h
        middle = 0.5 * (low + high)
        low, high = (middle, high) if siegmund_arl(middle, k) < arl0 else (low, middle)
    return high


def chi2_lower_quantile(dof: int, probability: float) -> float:
    """The ``probability`` quantile of a chi-square of ``dof`` degrees of freedom."""
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


def baseline_spread(values: np.ndarray, floor: float = 0.0) -> float:
    """The spread of a statistic from its baseline values: the sample standard deviation at its
    upper confidence bound (:data:`SPREAD_CONFIDENCE`), at least ``floor``.

    Raises
    ------
    ValueError
        With fewer than 3 values.
    """
    values = np.asarray(values, dtype=float)
    n = len(values)
    if n < 3:
        raise ValueError(f"the spread of a statistic needs at least 3 baseline windows, got {n}")
    spread = float(np.std(values, ddof=1))
    bound = math.sqrt((n - 1) / chi2_lower_quantile(n - 1, 1.0 - SPREAD_CONFIDENCE))
    return max(spread * bound, floor)


@dataclass
class Cusum:
    """Page's CUSUM on one statistic, one- or two-sided.

    Attributes
    ----------
    name : str
        The statistic.
    mean, spread : float
        Baseline mean and spread (the statistic's unit).
    threshold : float
        h, in spreads.
    two_sided : bool
        Also watch a fall (else a rise only).
    upper, lower : float
        The running sums (spreads).
    upper_start, lower_start : int
        The window after the last one at which each sum was 0: where a change began.
    crossed : int or None
        The window at which the test alarmed (None: not yet); it alarms once.
    """

    name: str
    mean: float
    spread: float
    threshold: float
    two_sided: bool = True
    upper: float = 0.0
    lower: float = 0.0
    upper_start: int = 0
    lower_start: int = 0
    crossed: int | None = None
    history: list[tuple[int, float]] = field(default_factory=list)

    def update(self, window: int, value: float) -> bool:
        """Feed the statistic of ``window``; True when the test alarms at this window."""
        z = (value - self.mean) / self.spread
        self.history.append((window, value))
        if self.upper == 0.0:
            self.upper_start = window
        if self.lower == 0.0:
            self.lower_start = window
        self.upper = max(0.0, self.upper + z - ALLOWANCE)
        if self.two_sided:
            self.lower = max(0.0, self.lower - z - ALLOWANCE)
        if self.crossed is None and self.score > 1.0:
            self.crossed = window
            return True
        return False

    @property
    def score(self) -> float:
        """The larger running sum over the threshold (1: at the threshold)."""
        return max(self.upper, self.lower) / self.threshold

    @property
    def direction(self) -> int:
        """+1 when the rise leads, -1 when the fall does."""
        return 1 if self.upper >= self.lower else -1

    @property
    def since(self) -> int:
        """The first window of the change the leading sum has gathered."""
        return self.upper_start if self.direction > 0 else self.lower_start

    def rate(self) -> float:
        """The statistic's change per window since :attr:`since` (its unit per window): the
        slope of a straight line through those windows' values, or the change of the one
        window over the baseline mean."""
        points = [(w, v) for w, v in self.history if w >= self.since]
        if len(points) < 2:
            return (points[-1][1] - self.mean) if points else 0.0
        w, v = np.array(points).T
        return float(np.polyfit(w, v, 1)[0])


def one_sided_tests(cusums: list[Cusum]) -> int:
    """How many one-sided tests the CUSUMs are (a two-sided one counts twice)."""
    return sum(2 if c.two_sided else 1 for c in cusums)


DEFAULT_TRACKED = ("coulomb_change", "backlash_change", "torque_ripple", "inertia_change")
MIN_BASELINE = 3
STEP_SHARE = 0.01  # finite-difference step of a tracked parameter: this share of its range
CALIBRATION_STEP = 0.001  # relative step of a calibrated parameter
CALIBRATION_ITERATIONS = 2
DESIGN_ARL = 10_000.0  # windows: the average run length to a false alarm of all tests together
# The smallest change of a calibrated parameter worth an alarm, relative to its nominal value
# (by the card's relative_size): a test's spread is at least that change. The baseline windows
# measure some parameters (backlash: about 1.6 nm on reference1) far more precisely than the
# calibration on those same windows places the twin; a drift of a thousandth of the nominal
# value still shows within two windows.
SMALLEST_RELEVANT_CHANGE = 0.001
UNEXPLAINED = "unexplained"
GAP_UNIT = "x noise floor"
CACHED_LINEARISATIONS = 16
# Beyond the linear range (a drift of many spreads), the update is refined (Gauss-Newton steps
# with the baseline's J): the twin replayed with the values found and the update applied to
# what it leaves, at most this many times, until a step moves the twin by less than REFINE_BELOW
# times the noise floor (RMS); a stationary window's first update moves it far less.
MAX_REFINEMENTS = 5
REFINE_BELOW = 0.05


@dataclass(frozen=True)
class TrackedParameter:
    """One parameter of a tracked effect (a hypothesis of the model's card).

    Attributes
    ----------
    effect : str
        The hypothesis.
    name : str
        Its parameter.
    unit : str
        The parameter's unit.
    step : float
        The finite-difference step, in its unit.
    relevant_per_unit : float or None
        The card's relative size of a change of one unit of the parameter (the others at
        their initial values), 1/unit; None for an effect that changes no calibrated
        parameter.
    """

    effect: str
    name: str
    unit: str
    step: float
    relevant_per_unit: float | None = None

    @property
    def key(self) -> str:
        """``effect.parameter``."""
        return f"{self.effect}.{self.name}"


def tracked_parameters(
    model: str, effects: tuple[str, ...], nominal: dict[str, float] | None = None
) -> list[TrackedParameter]:
    """The parameters of the tracked effects of a plant model's card (``nominal``: the FMU
    parameters their relative sizes are taken against; None: no relative sizes).

    Raises
    ------
    ValueError
        For an effect not in the card, or one fitted by scanning discrete values (it cannot be
        linearised).
    """
    library = {h.name: h for h in plant_model(model).hypotheses}
    found = []
    for effect in effects:
        hypothesis = library.get(effect)
        if hypothesis is None:
            raise ValueError(
                f"--track {effect}: not an effect of plant model {model!r}; expected some of "
                f"{sorted(library)}"
            )
        if hypothesis.kind != "continuous":
            raise ValueError(f"--track {effect}: fitted by a scan of discrete values; not tracked")
        initial = np.array([p.initial for p in hypothesis.parameters])
        for k, p in enumerate(hypothesis.parameters):
            step = STEP_SHARE * (p.upper - p.lower)
            if p.initial + step > p.upper:
                step = -step
            per_unit = None
            if hypothesis.relative_size is not None and nominal is not None:
                moved = initial.copy()
                moved[k] += step
                per_unit = abs(
                    hypothesis.relative_size(moved, nominal)
                    - hypothesis.relative_size(initial, nominal)
                ) / abs(step)
            found.append(TrackedParameter(effect, p.name, p.unit, step, per_unit))
    return found


@dataclass(frozen=True)
class Linearisation:
    """The baseline twin on one reference and the sensitivities of its normalised output.

    Attributes
    ----------
    position, current : numpy.ndarray
        The baseline twin at the compared samples, m and A.
    jacobian : numpy.ndarray
        (2 compared samples, tracked parameters): the change of the normalised position, then
        current, per unit of each parameter.
    pseudo_inverse : numpy.ndarray
        Its pseudo-inverse (the least-squares update).
    """

    position: np.ndarray
    current: np.ndarray
    jacobian: np.ndarray
    pseudo_inverse: np.ndarray


@dataclass(frozen=True)
class WindowCheck:
    """What the tracker found in one window.

    Attributes
    ----------
    window : int
        The window (counted from 0 in the order received).
    sequence : int
        The server's Sequence.
    phase : str
        ``baseline`` (calibrating on it) or ``tracking``.
    gap : Gap
        The gap against the twin (the baseline twin once calibrated).
    values : dict
        ``effect.parameter`` -> its value on top of the baseline (its unit); empty while the
        baseline is gathered.
    unexplained : float or None
        The normalised RMS gap the tracked effects' values leave (1: noise).
    tested : bool
        Whether the window fed the sequential tests.
    starts_at_rest : bool
        Whether its reference stood still at its start.
    check_s : float
        Wall time of replaying and checking it, s.
    twin : tuple of numpy.ndarray or None
        The twin's position (m) and current (A) at the window's samples.
    """

    window: int
    sequence: int
    phase: str
    gap: Gap
    values: dict[str, float]
    unexplained: float | None
    tested: bool
    starts_at_rest: bool
    check_s: float = 0.0
    twin: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)


@dataclass(frozen=True)
class Alarm:
    """A drift found by a sequential test.

    Attributes
    ----------
    window, sequence : int
        Where the test crossed its threshold.
    effect : str
        The drifting effect (a hypothesis of the card), or ``unexplained``.
    parameter : str
        Its parameter (``gap`` for the unexplained gap).
    unit : str
        The parameter's unit (``1`` for the gap).
    since : int
        The first window of the change.
    rate : float
        Change per window since then (the parameter's unit per window).
    value, baseline : float
        The window's value and the baseline mean.
    score : float
        The CUSUM over its threshold (>= 1).
    also : list of str
        Other tests that crossed at the same window.
    """

    window: int
    sequence: int
    effect: str
    parameter: str
    unit: str
    since: int
    rate: float
    value: float
    baseline: float
    score: float
    also: list[str] = field(default_factory=list)


@dataclass
class Baseline:
    """The calibrated twin and the statistics of the stationary machine.

    Attributes
    ----------
    parameters : dict
        The baseline twin's FMU parameters (on top of the scenario's).
    corrections : dict
        Relative change of each calibrated parameter (empty without calibration).
    floors : Floors
        The noise floors.
    windows : list of WindowCheck
        The baseline windows, checked against the calibrated twin.
    tests : dict
        Statistic name -> its CUSUM.
    repeating : bool
        Whether the baseline windows shared one reference (a repeating cycle).
    digests : set
        Their references' digests.
    calibration_s : float
        Wall time of the calibration and the first linearisation, s.
    """

    parameters: dict[str, float]
    corrections: dict[str, float]
    floors: Floors
    windows: list[WindowCheck]
    tests: dict[str, Cusum]
    repeating: bool
    digests: set[str]
    calibration_s: float


class Tracker:
    """The drift tracker of one axis (one plant instance, used from one thread).

    Parameters
    ----------
    scenario
        The scenario whose controller and plant the machine runs (plant parameters applied).
    plant
        The plant FMU instance the twin replays on.
    tracked
        The tracked effects (hypotheses of the plant model's card).
    baseline_windows
        How many first windows make the baseline.
    calibrate
        Whether to calibrate on them (False: the scenario's plant parameters are the baseline).
    design_arl
        Average run length (windows) to a false alarm of all tests together.
    """

    def __init__(
        self,
        scenario: Scenario,
        plant: Plant,
        tracked: tuple[str, ...] = DEFAULT_TRACKED,
        baseline_windows: int = 8,
        calibrate: bool = True,
        design_arl: float = DESIGN_ARL,
    ) -> None:
        if baseline_windows < MIN_BASELINE:
            raise ValueError(
                f"--baseline: at least {MIN_BASELINE} windows give a spread, got {baseline_windows}"
            )
        self.scenario = scenario
        self.plant = plant
        self.model = plant.description.coSimulation.modelIdentifier
        self.nominal = {**plant.start_values(), **scenario.plant_parameters}
        self.parameters = tracked_parameters(self.model, tuple(tracked), self.nominal)
        self.hypotheses = {h.name: h for h in plant_model(self.model).hypotheses}
        self.baseline_windows = baseline_windows
        self.calibrate = calibrate
        self.design_arl = design_arl
        self.gathered: list[tuple[Window, WindowCase, int]] = []
        self.baseline: Baseline | None = None
        self._linearisations: OrderedDict[str, Linearisation] = OrderedDict()
        self.precision: float | None = None  # of the calibration, relative (None: none made)

    @property
    def units(self) -> dict[str, str]:
        """Statistic -> unit: each tracked parameter's, and the unexplained gap's."""
        return {p.key: p.unit for p in self.parameters} | {UNEXPLAINED: GAP_UNIT}

    def check(self, index: int, window: Window, label: str) -> tuple[WindowCheck, list[Alarm]]:
        """Check window ``index`` (counted from 0): replay, gap, values, tests.

        Raises
        ------
        WindowError
            When the window is not sampled at the scenario's position-loop period.
        """
        case = window_case(self.scenario, window, label)
        if self.baseline is None:
            return self._gather(index, window, case), []
        return self._track(index, window, case)

    def _gather(self, index: int, window: Window, case: WindowCase) -> WindowCheck:
        """A baseline window: its gap against the uncalibrated twin, kept for the baseline."""
        res, record = residuals(window, case, self.plant, {})
        floors = noise_floors(res, window.period, estimate_resolution(window.position))
        self.gathered.append((window, case, index))
        check = WindowCheck(
            index,
            window.sequence,
            "baseline",
            gap_of(res, floors.sigma_position_m, floors.sigma_current),
            {},
            None,
            False,
            case.starts_at_rest,
            twin=(record["x"].copy(), record["current"].copy()),
        )
        return check

    @property
    def ready(self) -> bool:
        """Whether the baseline windows are all in and the baseline is still to be made."""
        return self.baseline is None and len(self.gathered) >= self.baseline_windows

    def make_baseline(self) -> Baseline:
        """Calibrate on the gathered windows, linearise, measure the statistics' scatter; the
        tracker then tracks."""
        start = time.perf_counter()
        floors = self._floors({})
        corrections: dict[str, float] = {}
        parameters: dict[str, float] = {}
        if self.calibrate:
            corrections = self._calibrate(floors)
            parameters = {n: self.nominal[n] * (1.0 + a) for n, a in corrections.items()}
            floors = self._floors(parameters)
        self._parameters, self._floors_now = parameters, floors
        self._linearisations.clear()
        checks = []
        for window, case, index in self.gathered:
            checks.append(self._values(index, window, case, tested=False)[0])
        digests = {case.digest for _, case, _ in self.gathered}
        tests = self._design_tests(checks)
        elapsed = time.perf_counter() - start
        self.baseline = Baseline(
            parameters, corrections, floors, checks, tests, len(digests) == 1, digests, elapsed
        )
        return self.baseline

    def _floors(self, parameters: dict[str, float]) -> Floors:
        """The noise floors of the gathered windows' residual against the twin at
        ``parameters`` (one replay per distinct reference)."""
        records: dict[str, RunRecord] = {}
        parts = []
        for window, case, _ in self.gathered:
            if case.digest not in records:
                records[case.digest] = run_scenario(
                    self.plant, case.scenario, plant_overrides=parameters
                )
            parts.append(residuals_against(window, case, records[case.digest]))
        x = np.concatenate([w.position for w, _, _ in self.gathered])
        return noise_floors(joined(parts), self.gathered[0][0].period, estimate_resolution(x))

    def _mean_by_case(self) -> list[tuple[WindowCase, np.ndarray, np.ndarray]]:
        """Per distinct reference: its case and the mean measured position (m) and current
        (A) of its windows at the compared samples."""
        groups: dict[str, list[tuple[Window, WindowCase]]] = {}
        for window, case, _ in self.gathered:
            groups.setdefault(case.digest, []).append((window, case))
        means = []
        for members in groups.values():
            case = members[0][1]
            x = np.mean([w.position[case.compared] for w, _ in members], axis=0)
            i = np.mean([w.current[case.compared] for w, _ in members], axis=0)
            means.append((case, x, i))
        return means

    def _calibrate(self, floors: Floors) -> dict[str, float]:
        """Relative corrections of the card's calibrated parameters (Gauss-Newton on the
        baseline windows, a Gaussian prior of width the calibration tolerance); sets
        :attr:`precision`, the largest standard error of a calibrated parameter moved alone
        (relative) under noise at the floors."""
        names = [n for n in plant_model(self.model).calibrated if self.nominal.get(n, 0.0) != 0]
        tolerance = DiagnosisSettings().calibration_tolerance
        a = np.zeros(len(names))
        sx, si = floors.sigma_position_m, floors.sigma_current
        for _ in range(CALIBRATION_ITERATIONS):
            rows, targets = [], []
            for case, x, i in self._mean_by_case():
                at = {n: self.nominal[n] * (1.0 + v) for n, v in zip(names, a, strict=True)}
                x0, i0 = (v[case.compared] for v in replay(self.plant, case, at))
                columns = []
                for k, name in enumerate(names):
                    ends = []
                    for sign in (1.0, -1.0):
                        moved = dict(at)
                        moved[name] = self.nominal[name] * (1.0 + a[k] + sign * CALIBRATION_STEP)
                        xk, ik = (v[case.compared] for v in replay(self.plant, case, moved))
                        ends.append(np.concatenate([xk / sx, ik / si]))
                    columns.append((ends[0] - ends[1]) / (2.0 * CALIBRATION_STEP))
                rows.append(np.column_stack(columns))
                targets.append(np.concatenate([(x - x0) / sx, (i - i0) / si]))
            jacobian, target = np.vstack(rows), np.concatenate(targets)
            prior = np.eye(len(names)) / tolerance
            system = np.vstack([jacobian, prior])
            rhs = np.concatenate([target, -prior @ a])
            a = a + np.linalg.lstsq(system, rhs, rcond=None)[0]
        self.precision = float(np.max(1.0 / np.linalg.norm(jacobian, axis=0)))
        return {n: float(v) for n, v in zip(names, a, strict=True)}

    def _overrides(self, key_values: dict[str, float]) -> dict[str, float]:
        """FMU parameters of the baseline twin with tracked parameters moved to ``key_values``
        (the others at their start values)."""
        parameters = dict(self._parameters)
        base = {**self.nominal, **parameters}
        for effect in dict.fromkeys(p.effect for p in self.parameters):
            hypothesis: Hypothesis = self.hypotheses[effect]
            values = np.array(
                [key_values.get(f"{effect}.{p.name}", p.initial) for p in hypothesis.parameters]
            )
            if any(f"{effect}.{p.name}" in key_values for p in hypothesis.parameters):
                parameters |= hypothesis.to_plant(values, base, _context())
        return parameters

    def _linearisation(self, case: WindowCase) -> Linearisation:
        """The baseline twin and its sensitivities on ``case``'s reference (made once)."""
        found = self._linearisations.get(case.digest)
        if found is not None:
            self._linearisations.move_to_end(case.digest)
            return found
        floors = self._floors_now
        sx, si = floors.sigma_position_m, floors.sigma_current
        x0, i0 = (v[case.compared] for v in replay(self.plant, case, self._parameters))
        columns = []
        for p in self.parameters:
            moved = self._overrides({p.key: self._initial(p) + p.step})
            xk, ik = (v[case.compared] for v in replay(self.plant, case, moved))
            columns.append(np.concatenate([(xk - x0) / sx, (ik - i0) / si]) / p.step)
        jacobian = np.column_stack(columns)
        found = Linearisation(x0, i0, jacobian, np.linalg.pinv(jacobian))
        self._linearisations[case.digest] = found
        if len(self._linearisations) > CACHED_LINEARISATIONS:
            self._linearisations.popitem(last=False)
        return found

    def _named(self, theta: np.ndarray) -> dict[str, float]:
        """Tracked values by ``effect.parameter`` from the changes ``theta`` of the update."""
        return {
            p.key: float(self._initial(p) + v) for p, v in zip(self.parameters, theta, strict=True)
        }

    def _initial(self, parameter: TrackedParameter) -> float:
        hypothesis = self.hypotheses[parameter.effect]
        return next(p.initial for p in hypothesis.parameters if p.name == parameter.name)

    def _values(
        self, index: int, window: Window, case: WindowCase, tested: bool
    ) -> tuple[WindowCheck, np.ndarray]:
        """The window against the baseline twin: gap, tracked values, what they leave."""
        floors = self._floors_now
        sx, si = floors.sigma_position_m, floors.sigma_current
        linear = self._linearisation(case)
        res, record = residuals(window, case, self.plant, self._parameters)
        r = np.concatenate([res.position / sx, res.current / si])
        theta = linear.pseudo_inverse @ r
        left = r - linear.jacobian @ theta
        step = theta
        for _ in range(MAX_REFINEMENTS):
            if np.sqrt(np.mean((linear.jacobian @ step) ** 2)) < REFINE_BELOW:
                break  # the last step moves the twin by a small part of the noise
            moved = self._overrides(self._named(theta))
            res_at, _ = residuals(window, case, self.plant, moved)
            r = np.concatenate([res_at.position / sx, res_at.current / si])
            step = linear.pseudo_inverse @ r
            theta = theta + step
            left = r - linear.jacobian @ step
        values = self._named(theta)
        check = WindowCheck(
            index,
            window.sequence,
            "tracking" if tested or self.baseline is not None else "baseline",
            gap_of(res, sx, si),
            values,
            float(np.sqrt(np.mean(left**2))),
            tested,
            case.starts_at_rest,
            twin=(record["x"].copy(), record["current"].copy()),
        )
        return check, theta

    def _design_tests(self, checks: list[WindowCheck]) -> dict[str, Cusum]:
        """A CUSUM per tracked parameter (two-sided) and on the unexplained gap (upwards),
        their means and spreads from the baseline windows (a spread at least the smallest
        relevant change, :data:`SMALLEST_RELEVANT_CHANGE`), thresholds for the design ARL."""
        tests = {p.key: Cusum(p.key, 0.0, 1.0, 0.0, two_sided=True) for p in self.parameters} | {
            UNEXPLAINED: Cusum(UNEXPLAINED, 0.0, 1.0, 0.0, two_sided=False)
        }
        threshold = threshold_for(self.design_arl * one_sided_tests(list(tests.values())))
        relevant = {
            p.key: SMALLEST_RELEVANT_CHANGE / p.relevant_per_unit
            for p in self.parameters
            if p.relevant_per_unit
        }
        for name, test in tests.items():
            values = np.array(
                [c.unexplained if name == UNEXPLAINED else c.values[name] for c in checks]
            )
            test.mean = float(np.mean(values))
            floor = max(_least_spread(test.mean), relevant.get(name, 0.0))
            test.spread = baseline_spread(values, floor=floor)
            test.threshold = threshold
        return tests

    def _track(
        self, index: int, window: Window, case: WindowCase
    ) -> tuple[WindowCheck, list[Alarm]]:
        """A window after the baseline: values, and the tests when its cycle was seen."""
        baseline = self.baseline
        assert baseline is not None
        tested = case.digest in baseline.digests or not baseline.repeating
        check, _ = self._values(index, window, case, tested)
        if not tested:
            return check, []
        crossed = []
        for name, test in baseline.tests.items():
            value = check.unexplained if name == UNEXPLAINED else check.values[name]
            if test.update(index, float(value)):
                crossed.append(test)
        if not crossed:
            return check, []
        crossed.sort(key=lambda t: -t.score)
        lead = crossed[0]
        effect, _, parameter = lead.name.partition(".")
        units = self.units
        alarm = Alarm(
            index,
            window.sequence,
            effect,
            parameter or "gap",
            units[lead.name],
            lead.since,
            lead.rate(),
            float(lead.history[-1][1]),
            lead.mean,
            lead.score,
            [t.name for t in crossed[1:]],
        )
        return check, [alarm]

    def describe_baseline(self) -> dict[str, Any]:
        """The baseline as the log records it."""
        baseline = self.baseline
        assert baseline is not None
        return {
            "event": "baseline",
            "windows": [c.window for c in baseline.windows],
            "calibrated": self.calibrate,
            "corrections": baseline.corrections,
            "calibration_precision": self.precision,
            "noise_floor_position_um": baseline.floors.sigma_position_m * 1e6,
            "noise_floor_current_ma": baseline.floors.sigma_current * 1e3,
            "repeating_cycle": baseline.repeating,
            "design_arl_windows": self.design_arl,
            "calibration_s": baseline.calibration_s,
            "units": self.units,
            "tests": {
                name: {"mean": t.mean, "spread": t.spread, "threshold": t.threshold}
                for name, t in baseline.tests.items()
            },
            "values": {
                str(c.window): {**c.values, UNEXPLAINED: c.unexplained} for c in baseline.windows
            },
            "gaps": {str(c.window): c.gap.normalised_rms for c in baseline.windows},
        }


def _context() -> dict[str, float]:
    """Orders of the periodic effects tracked (the card's defaults: no data to read them from)."""
    from twin_cosim.gap.data.context import DEFAULT_CONTEXT

    return dict(DEFAULT_CONTEXT)


def _least_spread(mean: float) -> float:
    """A spread never below the float resolution of the statistic's mean."""
    return max(abs(mean) * 1e-12, math.ulp(1.0))
