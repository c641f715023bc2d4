"""``twin friction``: the friction curve as drives measure it, fitted and written as
``plant.yaml``.

**The runs** (on the twin): per direction one run through levels of constant motor speed,
log-spaced from the highest speed down to the lowest (:func:`~twin_cosim.servo.motion.speed_levels`:
each level reached from the one above on a gentle ramp and held for the dwell). At a constant
speed nothing accelerates, so the motor torque the drive commands, K_t times the mean current
over the level's steady window, is the friction torque at that speed (motor-referred, N.m; the
drive's torque constant, as a drive converts its current). The current includes whatever the
position loop, the speed loop's integrator and the feedforwards command: all of it is torque the
motor gives, and at constant speed all of it goes into friction.

A level is **steady** when the motor speed's spread over its window is within
:data:`STEADY_SPREAD` of its mean. Where friction falls with speed (Stribeck) faster than the
coupling's damping can carry, B + dF/dw < 0, the load cannot slide evenly: it sticks and slips
(a limit cycle near the first antiresonance), and the mean current there is the cycle's mean,
not the curve's value; such a level's mean is drawn, never fitted. Its samples still carry the
curve: while the load slides, the torque balance of the two masses,

    F = K_t i - J_M dw_M/dt - J_L dw_L/dt

(the drive's current less the inertias' torque, from the motor speed and the scale's load
speed; the plant model's J_M and J_L) is the friction at the load speed w_L of that moment
(:func:`torque_balance`). The samples of the stick-slip levels where the load slides, away from
a stick, are gathered per direction into :data:`BALANCE_BINS_PER_DECADE` bins of load speed,
each bin's median a point of the curve ("torque balance"), fitted with the steady levels. A drive
with a linear scale measures the same; without the plant's inertias (no ``linear`` section in
its card) the stick-slip levels are left out. The Stribeck terms are reported as identified only
where the fitted points resolve them.

**The fit**, per direction d (+1, -1), on the magnitudes of speed w (rad/s) and torque (N.m)::

    |tau| = F_C,d + F_V,d |w| + F_S,d exp(-(|w| / v_S,d)^2)

(the plant model's friction, eq. (5) with the card's Stribeck and asymmetry effects:
F_C,d = coulomb_friction + d coulomb_asymmetry, F_S = stribeck_friction, v_S = stribeck_speed,
F_V = viscous_friction). Least squares (SciPy), v_S in its logarithm; each value's uncertainty is
its standard error (the residual's variance times the inverse of JtJ). The Stribeck rise counts
when it exceeds twice its standard error and :data:`STRIBECK_FLOOR` of the Coulomb level and the
steady levels reach into it (the lowest steady speed below 2 v_S); otherwise the fit is done
again without it and the Stribeck terms are not identified (null, with the reason). The joint fit
(the plant's form: a Coulomb level per direction, one viscous coefficient, one Stribeck rise)
gives ``coulomb_positive``, ``coulomb_negative``, ``viscous``, ``stribeck_friction`` and
``stribeck_speed``; it is the one written as ``plant.yaml`` (coulomb_friction, coulomb_asymmetry,
viscous_friction, stribeck_friction, stribeck_speed).

**Measured runs** (``--measured FILE``): a CSV of such runs, ``t`` [s], ``torque`` [N.m] or
``current`` [A] (times the scenario's torque constant), ``motor_speed`` [rad/s] or ``x`` [m]
(differentiated, over the travel per motor radian); extra columns ignored. Its levels of steady
speed are found in the data (:func:`measured_levels`) and fitted the same way.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model
from twin_cosim.report import text_table
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.plant_parameters import PlantParameters, fitted_plant
from twin_cosim.servo.motion import level_statistics, run_motion, speed_levels

SPEEDS = 24  # levels per direction
DWELL_S = 0.5  # s at each level
LOWEST_SPEED = 0.02  # rad/s at the motor
STEADY_SPREAD = 0.05  # the largest standard deviation of a steady level's speed, of its mean
STRIBECK_FLOOR = 0.01  # of the Coulomb level: a smaller rise is no Stribeck effect
PLANT_PARAMETERS = (
    "coulomb_friction",
    "coulomb_asymmetry",
    "viscous_friction",
    "stribeck_friction",
    "stribeck_speed",
)
MIN_LEVEL_S = 0.2  # s: a measured level of steady speed lasts at least this long
MIN_POINTS = 3  # fitted points per direction a fit needs
BALANCE_BINS_PER_DECADE = 10  # torque-balance points per decade of load speed
MIN_BIN_SAMPLES = 5  # samples a torque-balance point needs
INERTIAL_SHARE = 0.1  # the largest inertial torque of a torque-balance sample, of its friction
STRIBECK_STARTS = 8  # Stribeck speeds the fit starts from, log-spaced over the points' speeds


class FrictionDataError(ValueError):
    """A measured file cannot be used; the message names the file, the column and the problem."""


KINDS = ("steady level", "stick-slip level", "torque balance")


@dataclass(frozen=True)
class FrictionPoint:
    """One point of the friction curve.

    Attributes
    ----------
    speed : float
        Motor speed (the load's, motor-referred, for a torque-balance point), rad/s (signed).
    torque : float
        Torque, N.m (signed).
    speed_spread : float
        Standard deviation of the speed over the level's window (of the bin's samples), rad/s.
    kind : str
        ``steady level`` (fitted), ``stick-slip level`` (the cycle's mean, not fitted) or
        ``torque balance`` (a bin of the stick-slip levels' sliding samples, fitted).
    """

    speed: float
    torque: float
    speed_spread: float
    kind: str

    @property
    def fitted(self) -> bool:
        """Whether the fit uses it."""
        return self.kind != "stick-slip level"

    @classmethod
    def of_samples(
        cls, speed: np.ndarray, torque: np.ndarray, kind: str, centre: Any = np.mean
    ) -> FrictionPoint:
        """The point of samples of speed (rad/s) and torque (N.m): their ``centre`` (mean or
        median), and the speed's spread."""
        return cls(float(centre(speed)), float(centre(torque)), float(np.std(speed)), kind)


@dataclass(frozen=True)
class FrictionFit:
    """A fit of the friction model (module docstring) with each value's standard error.

    ``values`` and ``uncertainty`` by name: ``coulomb_positive``, ``coulomb_negative`` (N.m,
    magnitudes), ``viscous`` (N.m.s/rad), ``stribeck_friction`` (N.m), ``stribeck_speed``
    (rad/s); the Stribeck terms None when not identified (``not_identified`` says why).
    ``rms`` is the RMS residual, N.m.
    """

    values: dict[str, float | None]
    uncertainty: dict[str, float | None]
    rms: float
    not_identified: dict[str, str] = field(default_factory=dict)

    def torque(self, speed: np.ndarray) -> np.ndarray:
        """The fitted torque (N.m, signed) at signed motor speeds (rad/s)."""
        w = np.asarray(speed, dtype=np.float64)
        v = self.values
        coulomb = np.where(w >= 0, v["coulomb_positive"], v["coulomb_negative"])
        level = coulomb + v["viscous"] * np.abs(w)
        if v["stribeck_friction"] is not None:
            level = level + v["stribeck_friction"] * np.exp(-((w / v["stribeck_speed"]) ** 2))
        return np.sign(w) * level


@dataclass(frozen=True)
class FrictionResult:
    """The friction curve of an axis: its points, the joint fit and the per-direction fits.

    Attributes
    ----------
    source : str
        Where the points came from (the twin's runs, or the measured file).
    points : list of FrictionPoint
        Every level, positive speeds then negative.
    fit : FrictionFit
        The plant's form: a Coulomb level per direction, shared viscous and Stribeck terms.
    directions : dict
        ``positive`` and ``negative``: each direction fitted on its own (its ``coulomb_*`` the
        direction's, the other None).
    """

    source: str
    points: list[FrictionPoint]
    fit: FrictionFit
    directions: dict[str, FrictionFit]

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the joint fit's values at the top, their uncertainties, the directions,
        the points."""
        return {
            "source": self.source,
            **self.fit.values,
            "uncertainty": self.fit.uncertainty,
            "units": {
                "coulomb_positive": "N.m",
                "coulomb_negative": "N.m",
                "viscous": "N.m.s/rad",
                "stribeck_friction": "N.m",
                "stribeck_speed": "rad/s",
            },
            "rms_residual_n_m": self.fit.rms,
            "not_identified": self.fit.not_identified,
            "directions": {
                name: {
                    **fit.values,
                    "uncertainty": fit.uncertainty,
                    "rms_residual_n_m": fit.rms,
                    "not_identified": fit.not_identified,
                }
                for name, fit in self.directions.items()
            },
            "points": [asdict(p) for p in self.points],
        }


def default_speeds(scenario: Scenario, count: int = SPEEDS) -> np.ndarray:
    """Motor speeds (rad/s), log-spaced from the scenario's fastest reference speed down to
    :data:`LOWEST_SPEED`, highest first."""
    fastest = float(np.max(np.abs(scenario.reference.velocity))) / scenario.settings.travel_per_rad
    if not fastest > LOWEST_SPEED:
        raise ValueError(
            f"{scenario.source}: the reference's fastest motor speed {fastest:.3g} rad/s is not "
            f"above {LOWEST_SPEED:g} rad/s; give --max-speed"
        )
    return np.geomspace(fastest, LOWEST_SPEED, count)


def twin_points(
    plant: Plant, scenario: Scenario, speeds: Sequence[float], dwell_s: float = DWELL_S
) -> list[FrictionPoint]:
    """The friction points of ``scenario``'s axis at each motor speed (rad/s, magnitudes; run
    from the highest down) in both directions, each held ``dwell_s`` (s): each level's mean,
    and the torque balance of the levels that stick and slip (module docstring)."""
    settings = scenario.settings
    travel = settings.travel_per_rad
    ordered = sorted((float(w) for w in speeds), reverse=True)
    if not ordered or ordered[-1] <= 0:
        raise ValueError(f"friction speeds: expected speeds above 0 rad/s, got {ordered}")
    model = plant_model(scenario.model_name())
    inertias = None
    if model.two_mass:
        linear = model.linear_plant(scenario.plant_parameters)
        inertias = (linear["motor_inertia"], linear["load_inertia"])
    points = []
    start = float(scenario.reference.position[0])
    for sign in (1.0, -1.0):
        grid, levels = speed_levels(
            [sign * w * travel for w in ordered], dwell_s, settings.position_period, start
        )
        record = run_motion(
            plant, grid, scenario.tuned, settings, scenario.plant_parameters
        ).position_loop
        current, _ = level_statistics(record, levels, "current")
        speed, spread = level_statistics(record, levels, "motor_speed")
        steady = spread <= STEADY_SPREAD * np.abs(speed)
        for w, i, s, even in zip(speed, current, spread, steady, strict=True):
            kind = "steady level" if even else "stick-slip level"
            points.append(
                FrictionPoint(float(w), float(i * settings.torque_constant), float(s), kind)
            )
        if inertias is not None and not steady.all():
            load_speed, friction, inertial = torque_balance(
                record, settings.torque_constant, travel, *inertias
            )
            sliding = np.zeros(len(load_speed), dtype=bool)
            lowest = sign * min(ordered)
            for level, even in zip(levels, steady, strict=True):
                if not even:
                    sliding[level.steady] = True
            moving = load_speed * sign > 0.5 * abs(lowest)
            sliding &= moving & np.roll(moving, 1) & np.roll(moving, -1)  # away from a stick
            sliding &= np.abs(inertial) <= INERTIAL_SHARE * np.abs(friction)
            points += balance_points(load_speed[sliding], friction[sliding])
    return points


def torque_balance(
    record: Any, torque_constant: float, travel: float, motor_inertia: float, load_inertia: float
) -> tuple[np.ndarray, np.ndarray]:
    """The load speed (rad/s, motor-referred) and friction torque (N.m) at each position-loop
    sample of a record: F = K_t i - J_M dw_M/dt - J_L dw_L/dt (``torque_constant`` N.m/A,
    ``travel`` m/rad, the inertias kg.m2), by central differences of the motor speed and of the
    scale reading; the current is the mean over the sample's two neighbouring periods. The
    first and last samples are NaN."""
    q = np.asarray(record["x"]) / travel
    w_m = np.asarray(record["motor_speed"])
    i = np.asarray(record["current"])
    dt = float(np.median(np.diff(np.asarray(record["t"]))))
    load_speed = np.full(len(q), np.nan)
    inertial = np.full(len(q), np.nan)
    load_speed[1:-1] = (q[2:] - q[:-2]) / (2 * dt)
    load_acceleration = (q[2:] - 2 * q[1:-1] + q[:-2]) / dt**2
    motor_acceleration = (w_m[2:] - w_m[:-2]) / (2 * dt)
    inertial[1:-1] = motor_inertia * motor_acceleration + load_inertia * load_acceleration
    current = np.full(len(q), np.nan)
    current[1:-1] = 0.5 * (i[1:-1] + i[:-2])
    return load_speed, torque_constant * current - inertial, inertial


def balance_points(load_speed: np.ndarray, friction: np.ndarray) -> list[FrictionPoint]:
    """Torque-balance samples of one direction gathered into log-spaced bins of load speed
    (:data:`BALANCE_BINS_PER_DECADE`), each bin of at least :data:`MIN_BIN_SAMPLES` samples a
    point at its median speed and torque."""
    if len(load_speed) < MIN_BIN_SAMPLES:
        return []
    magnitude = np.abs(load_speed)
    edges = np.arange(
        math.floor(math.log10(magnitude.min()) * BALANCE_BINS_PER_DECADE),
        math.ceil(math.log10(magnitude.max()) * BALANCE_BINS_PER_DECADE) + 1,
    )
    bins = np.digitize(np.log10(magnitude) * BALANCE_BINS_PER_DECADE, edges)
    points = []
    for b in np.unique(bins):
        inside = bins == b
        if inside.sum() >= MIN_BIN_SAMPLES:
            points.append(
                FrictionPoint.of_samples(
                    load_speed[inside], friction[inside], "torque balance", np.median
                )
            )
    return points


def fit_friction(points: Sequence[FrictionPoint]) -> tuple[FrictionFit, dict[str, FrictionFit]]:
    """The joint fit and the per-direction fits of the fitted points (module docstring).

    Raises
    ------
    ValueError
        With fewer than :data:`MIN_POINTS` points to fit in a direction.
    """
    sides = {}
    for name, sign in (("positive", 1.0), ("negative", -1.0)):
        chosen = [p for p in points if p.fitted and p.speed * sign > 0]
        if len(chosen) < MIN_POINTS:
            raise ValueError(
                f"friction: {len(chosen)} points to fit in the {name} direction; a fit needs "
                f"{MIN_POINTS} (the means of levels that stick and slip are not fitted)"
            )
        w = np.array([abs(p.speed) for p in chosen])
        tau = np.array([p.torque * sign for p in chosen])
        sides[name] = (w, tau)
    directions = {name: _fit({name: data}) for name, data in sides.items()}
    return _fit(sides), directions


def _fit(sides: dict[str, tuple[np.ndarray, np.ndarray]]) -> FrictionFit:
    """Fit one Coulomb level per side, a shared viscous coefficient and a shared Stribeck rise
    (tested for, and left out when the data do not resolve it)."""
    names = list(sides)
    starts = []
    for w, tau in sides.values():
        fast = w >= np.median(w)
        slope, intercept = np.polyfit(w[fast], tau[fast], 1) if fast.sum() > 1 else (0.0, tau[0])
        starts.append((max(intercept, 1e-6), max(slope, 0.0), w, tau - intercept - slope * w))
    coulombs = [s[0] for s in starts]
    viscous = float(np.mean([s[1] for s in starts]))
    all_w = np.concatenate([s[2] for s in starts])
    rise = max(float(np.concatenate([s[3] for s in starts])[np.argmin(all_w)]), 1e-6)

    def residual(theta: np.ndarray, stribeck: bool) -> np.ndarray:
        parts = []
        for k, (w, tau) in enumerate(sides.values()):
            model = theta[k] + theta[len(names)] * w
            if stribeck:
                model = model + theta[-2] * np.exp(-((w / math.exp(theta[-1])) ** 2))
            parts.append(model - tau)
        return np.concatenate(parts)

    lowest, highest = float(all_w.min()), float(all_w.max())
    bounds = (
        [0.0] * len(names) + [0.0, 0.0, math.log(lowest / 3)],
        [np.inf] * len(names) + [np.inf, np.inf, math.log(highest)],
    )
    with_rise = min(  # from several Stribeck speeds: the rise is seen by few points
        (
            least_squares(
                residual,
                np.array([*coulombs, viscous, rise, math.log(speed)]),
                bounds=bounds,
                args=(True,),
                x_scale="jac",
            )
            for speed in np.geomspace(lowest, highest, STRIBECK_STARTS)
        ),
        key=lambda found: found.cost,
    )
    errors = _standard_errors(with_rise)
    v_s = math.exp(with_rise.x[-1])
    reasons = {}
    if not with_rise.x[-2] > max(
        2 * errors[-2], STRIBECK_FLOOR * float(np.mean(with_rise.x[: len(names)]))
    ):
        reasons["stribeck_friction"] = (
            "the fitted points show no rise of the friction at low speed beyond its uncertainty"
        )
    elif not lowest < 2 * v_s:
        reasons["stribeck_friction"] = (
            f"no fitted point below 2 v_S = {2 * v_s:.3g} rad/s resolves the rise (the lowest: "
            f"{lowest:.3g} rad/s)"
        )
    found = with_rise
    if reasons:
        reasons["stribeck_speed"] = reasons["stribeck_friction"]
        found = least_squares(
            residual,
            with_rise.x[: len(names) + 1],
            bounds=([0.0] * (len(names) + 1), [np.inf] * (len(names) + 1)),
            args=(False,),
            x_scale="jac",
        )
        errors = _standard_errors(found)
    values: dict[str, float | None] = {"coulomb_positive": None, "coulomb_negative": None}
    uncertainty: dict[str, float | None] = dict(values)
    for k, name in enumerate(names):
        values[f"coulomb_{name}"] = float(found.x[k])
        uncertainty[f"coulomb_{name}"] = float(errors[k])
    values["viscous"] = float(found.x[len(names)])
    uncertainty["viscous"] = float(errors[len(names)])
    if reasons:
        values |= {"stribeck_friction": None, "stribeck_speed": None}
        uncertainty |= {"stribeck_friction": None, "stribeck_speed": None}
    else:
        values["stribeck_friction"] = float(found.x[-2])
        values["stribeck_speed"] = v_s
        uncertainty["stribeck_friction"] = float(errors[-2])
        uncertainty["stribeck_speed"] = v_s * float(errors[-1])  # d v_S = v_S d log(v_S)
    rms = float(np.sqrt(np.mean(found.fun**2)))
    return FrictionFit(values, uncertainty, rms, reasons)


def _standard_errors(found: Any) -> np.ndarray:
    """Each parameter's standard error: the residual's variance times the inverse of JtJ."""
    jacobian = found.jac
    dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * (2.0 * found.cost / dof)
    return np.sqrt(np.clip(np.diag(covariance), 0.0, None))


def friction_curve(
    plant: Plant, scenario: Scenario, speeds: Sequence[float], dwell_s: float = DWELL_S
) -> FrictionResult:
    """The twin's friction curve: its runs (:func:`twin_points`) and their fit."""
    points = twin_points(plant, scenario, speeds, dwell_s)
    fit, directions = fit_friction(points)
    source = (
        f"the twin: {len(speeds)} levels per direction from {max(speeds):.3g} down to "
        f"{min(speeds):.3g} rad/s, {dwell_s:g} s each"
    )
    return FrictionResult(source, points, fit, directions)


def measured_curve(path: Path | str, scenario: Scenario) -> FrictionResult:
    """The friction curve of a measured file of constant-speed runs (:func:`measured_levels`)."""
    points = measured_levels(path, scenario)
    fit, directions = fit_friction(points)
    return FrictionResult(str(path), points, fit, directions)


def measured_levels(path: Path | str, scenario: Scenario) -> list[FrictionPoint]:
    """The levels of steady speed in a measured CSV and their mean torque.

    A level is a stretch of at least :data:`MIN_LEVEL_S` where the speed, smoothed over
    :data:`MIN_LEVEL_S` / 4, changes by less than :data:`STEADY_SPREAD` of itself per
    :data:`MIN_LEVEL_S` (or less than the acceleration's noise, three of its robust standard
    deviations) and lies above the speed's noise (three times its sample-to-sample spread): no
    acceleration torque is in it. Its mean torque and speed are taken over its second half.

    Raises
    ------
    FrictionDataError
        Naming the file and the column: a missing file or column, values that are not finite
        numbers, time that does not increase.
    """
    import pandas as pd

    path = Path(path)
    if not path.is_file():
        raise FrictionDataError(f"{path}: measured file not found")
    try:
        frame = pd.read_csv(path, comment="#")
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise FrictionDataError(f"{path}: not a CSV file with a header row: {exc}") from None
    columns = {str(c).strip(): c for c in frame.columns}

    def column(name: str) -> np.ndarray:
        values = pd.to_numeric(frame[columns[name]], errors="coerce").to_numpy(np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise FrictionDataError(
                f"{path}: column {name}: {frame[columns[name]].iloc[bad[0]]!r} in data row "
                f"{bad[0] + 1} is not a finite number"
            )
        return values

    if "t" not in columns:
        raise FrictionDataError(f"{path}: no column t [s]; columns: {list(columns)}")
    t = column("t")
    if len(t) < 10 or np.any(np.diff(t) <= 0):
        raise FrictionDataError(f"{path}: column t: expected at least 10 increasing times in s")
    if "torque" in columns:
        torque = column("torque")
    elif "current" in columns:
        torque = column("current") * scenario.settings.torque_constant
    else:
        raise FrictionDataError(
            f"{path}: expected a column torque [N.m] or current [A]; columns: {list(columns)}"
        )
    if "motor_speed" in columns:
        speed = column("motor_speed")
    elif "x" in columns:
        speed = np.gradient(column("x"), t) / scenario.settings.travel_per_rad
    else:
        raise FrictionDataError(
            f"{path}: expected a column motor_speed [rad/s] or x [m]; columns: {list(columns)}"
        )
    return _levels(t, speed, torque)


def _levels(t: np.ndarray, speed: np.ndarray, torque: np.ndarray) -> list[FrictionPoint]:
    """The levels of steady speed (see :func:`measured_levels`), in time order."""
    dt = float(np.median(np.diff(t)))
    width = max(1, round(MIN_LEVEL_S / 4 / dt))
    smooth = np.convolve(speed, np.ones(width) / width, mode="same")
    acceleration = np.gradient(smooth, t)
    inner = slice(width, len(t) - width)  # where the moving average sees no edge
    spread = float(np.median(np.abs(acceleration[inner] - np.median(acceleration[inner]))))
    speed_noise = 3.0 * float(np.median(np.abs(np.diff(speed)))) / 0.6745 / math.sqrt(2)
    allowed = np.maximum(STEADY_SPREAD * np.abs(smooth) / MIN_LEVEL_S, 3.0 * spread / 0.6745)
    steady = (np.abs(acceleration) <= allowed) & (np.abs(smooth) > speed_noise)
    steady[:width] = steady[-width:] = False
    points = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], steady.astype(int), [0]])))
    for begin, end in zip(edges[::2], edges[1::2], strict=True):
        end = end - width  # the average reaches past a level's end by half its width
        if end - begin < 2 or t[end - 1] - t[begin] < MIN_LEVEL_S:
            continue
        half = slice((begin + end) // 2, end)
        points.append(FrictionPoint.of_samples(speed[half], torque[half], "steady level"))
    return points


def plant_file(result: FrictionResult, scenario: Scenario, command: str) -> PlantParameters:
    """The joint fit as the plant model's friction parameters (module docstring), with where
    they came from.

    Raises
    ------
    PlantModelError
        When the scenario's plant model has not these parameters.
    """
    model = scenario.model_name()
    plant_model(model).require_parameters(PLANT_PARAMETERS, "twin friction writes the parameters")
    v = result.fit.values
    parameters = {
        "coulomb_friction": 0.5 * (v["coulomb_positive"] + v["coulomb_negative"]),
        "coulomb_asymmetry": 0.5 * (v["coulomb_positive"] - v["coulomb_negative"]),
        "viscous_friction": v["viscous"],
        "stribeck_friction": v["stribeck_friction"] or 0.0,
    }
    if v["stribeck_speed"] is not None:
        parameters["stribeck_speed"] = v["stribeck_speed"]
    counts = {kind: sum(p.kind == kind for p in result.points) for kind in KINDS}
    source = (
        f"twin friction: {counts['steady level']} steady levels of constant speed and "
        f"{counts['torque balance']} torque-balance points of {counts['stick-slip level']} "
        f"levels that stuck and slipped ({result.source}), fitted to Coulomb, viscous and "
        f"Stribeck terms, RMS residual {result.fit.rms:.3g} N.m"
    )
    return fitted_plant(
        model, parameters, source, command, not_identified=result.fit.not_identified
    )


def describe(result: FrictionResult) -> str:
    """The fits as a short table with units (``friction.txt``)."""

    def cell(fit: FrictionFit, name: str) -> str:
        value = fit.values[name]
        if value is None:
            return "-"
        return f"{value:.4g} +- {fit.uncertainty[name]:.2g}"

    rows = []
    for name, unit in (
        ("coulomb_positive", "N.m"),
        ("coulomb_negative", "N.m"),
        ("viscous", "N.m.s/rad"),
        ("stribeck_friction", "N.m"),
        ("stribeck_speed", "rad/s"),
    ):
        rows.append(
            (
                f"{name} [{unit}]",
                cell(result.fit, name),
                cell(result.directions["positive"], name),
                cell(result.directions["negative"], name),
            )
        )
    table = text_table(("quantity", "joint fit", "positive alone", "negative alone"), rows)
    unsteady = [p for p in result.points if p.kind == "stick-slip level"]
    notes = [f"{name}: not identified: {why}" for name, why in result.fit.not_identified.items()]
    if unsteady:
        ranges = []
        for name, sign in (("positive", 1.0), ("negative", -1.0)):
            speeds = [abs(p.speed) for p in unsteady if p.speed * sign > 0]
            if speeds:
                ranges.append(
                    f"{len(speeds)} {name} levels at {min(speeds):.3g}-{max(speeds):.3g} rad/s"
                )
        balance = sum(p.kind == "torque balance" for p in result.points)
        notes.append(
            f"stick-slip: {', '.join(ranges)}: their means not fitted; {balance} "
            "torque-balance points of their sliding samples fitted instead"
        )
    return table + "".join(f"{note}\n" for note in notes)


def plot_friction(result: FrictionResult, path: Path, command: str) -> Path:
    """Torque magnitude against speed magnitude (log scale), each direction's points (hollow
    where the level stuck and slipped) and fitted curves; returns ``path``."""
    from twin_cosim.plots import save_figure, stacked_axes

    fig, (ax,) = stacked_axes(1, (9, 6), [1])
    speeds = np.array([abs(p.speed) for p in result.points])
    grid = np.geomspace(max(speeds.min(), 1e-4), speeds.max(), 300)
    styles = {
        "steady level": {"marker": "o", "ls": "none"},
        "stick-slip level": {"marker": "o", "ls": "none", "mfc": "none"},
        "torque balance": {"marker": "x", "ls": "none", "ms": 5},
    }
    labels = {
        "steady level": "steady levels",
        "stick-slip level": "levels that stick and slip (the cycle's mean, not fitted)",
        "torque balance": "torque balance while sliding (fitted)",
    }
    for name, sign, color in (("positive", 1.0, "tab:blue"), ("negative", -1.0, "tab:orange")):
        for kind in KINDS:
            chosen = [p for p in result.points if p.speed * sign > 0 and p.kind == kind]
            if chosen:
                ax.semilogx(
                    [abs(p.speed) for p in chosen],
                    [abs(p.torque) for p in chosen],
                    color=color,
                    label=f"{name}: {labels[kind]}",
                    **styles[kind],
                )
        ax.semilogx(
            grid,
            np.abs(result.fit.torque(sign * grid)),
            color=color,
            lw=1.2,
            label=f"fit, {name}: " + _fit_label(result.fit, name),
        )
    ax.set_xlabel("motor speed |w| [rad/s]")
    ax.set_ylabel("steady torque |K_t i| [N.m]")
    ax.set_ylim(0.0, 1.1 * max(abs(p.torque) for p in result.points))  # from 0, as drives draw it
    ax.set_title(f"friction curve: {result.source}\n{command}", fontsize=9)
    ax.legend(fontsize=8)
    return save_figure(fig, [ax], path)


def _fit_label(fit: FrictionFit, direction: str) -> str:
    """A fit's values for one direction in a legend."""
    v = fit.values
    text = f"F_C {v[f'coulomb_{direction}']:.3g} N.m, F_V {v['viscous']:.3g} N.m.s/rad"
    if v["stribeck_friction"] is not None:
        text += f", F_S {v['stribeck_friction']:.3g} N.m, v_S {v['stribeck_speed']:.3g} rad/s"
    return text
