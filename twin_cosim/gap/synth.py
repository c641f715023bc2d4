"""The virtual machine: the twin with unmodelled effects switched on, calibration error and
measurement noise, writing a measured-run CSV whose answer is known.

Effects are given as ``NAME:param=value,...`` with NAME from the hypothesis library (the ``effects``
of the model's card, :mod:`twin_cosim.plant_model`) and either all of that hypothesis' parameters
(as the diagnosis reports them, e.g. ``inertia_change:relative_change=0.2``) or FMU parameters of
its block (e.g. ``torque_ripple:ripple_amplitude=0.05,ripple_order=8``); ``plant:NAME=value,...``
sets any FMU parameter (effects outside the library: ``plant:pitch_error_amplitude_3=2e-6``,
``plant:lugre_stiffness=2000``, ``plant:thermal_expansion_rate=1e-4``).

Calibration error: each calibrated parameter of the plant model (``calibrated`` of its card,
:mod:`twin_cosim.plant_model`) is multiplied by (1 + u), u uniform in [-perturb, perturb].

Every value the FMU would refuse is refused before anything runs (:func:`check_machine`): each
parameter an effect or the calibration error sets against its range in the model's variable
table, and the whole plant against the card's constraints, the error naming the ``--effect`` (or
``--perturb``), the parameter, its value and the range.
Measurement noise: white, Gaussian, on the position (m) and the current (A), on top of the
scenario's noise harmonics; with an encoder resolution set, the noisy position is quantised again,
as an encoder's readings stay on its grid.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.controller import ControllerSettings
from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.context import DEFAULT_CONTEXT, library_for
from twin_cosim.gap.data.regimes import REGIMES, STANDSTILL, classify_regimes, strokes
from twin_cosim.plant import Plant
from twin_cosim.plant_model import model_names, plant_model
from twin_cosim.reference import (
    Dwell,
    Move,
    Oscillation,
    Ramp,
    ReferenceGrid,
    Segment,
    interpolate,
    sample_segments,
    segments_duration,
)
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.machine import DEFAULT_LIMITS, AxisLimits
from twin_cosim.scenario.plant_parameters import dump_yaml, relocate_paths
from twin_cosim.schema import load_yaml


@dataclass(frozen=True)
class EffectSpec:
    """One effect to switch on: a library name (or ``plant``) and its parameters; ``text`` as
    the command line gave it (for messages)."""

    name: str
    params: dict[str, float]
    text: str = ""

    @property
    def option(self) -> str:
        """The option that asked for it, for messages."""
        return f"--effect {self.text or self.name}"


def parse_effect(text: str) -> EffectSpec:
    """Parse ``NAME:param=value,param=value``; ValueError says what was expected."""
    name, _, body = text.partition(":")
    known = sorted({h.name for model in model_names() for h in plant_model(model).hypotheses})
    if name != "plant" and name not in known:
        raise ValueError(
            f"--effect {text!r}: unknown effect {name!r}; expected 'plant' or one of {known}"
        )
    params = {}
    for item in filter(None, body.split(",")):
        key, equals, value = item.partition("=")
        try:
            params[key.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--effect {text!r}: {item!r} must be param=number") from None
        if not equals or not np.isfinite(params[key.strip()]):
            raise ValueError(f"--effect {text!r}: {item!r} must be param=finite number")
    if not params:
        raise ValueError(f"--effect {text!r}: give at least one param=value after '{name}:'")
    return EffectSpec(name, params, text)


def effect_overrides(
    effect: EffectSpec, nominal: dict[str, float], fmu_parameters: set[str], model: str
) -> dict[str, float]:
    """FMU parameters that switch one effect on in a plant of the given model."""
    if effect.name == "plant" or set(effect.params) <= fmu_parameters:
        unknown = sorted(set(effect.params) - fmu_parameters)
        if unknown:
            raise ValueError(f"effect {effect.name}: the FMU has no parameter(s) {unknown}")
        return dict(effect.params)
    by_name = {h.name: h for h in library_for(model)}
    if effect.name not in by_name:
        raise ValueError(
            f"effect {effect.name}: not an effect of plant model {model!r}; "
            f"expected one of {sorted(by_name)} or 'plant'"
        )
    hypothesis = by_name[effect.name]
    names = [p.name for p in hypothesis.parameters]
    extra = sorted(set(effect.params) - set(names) - {"order"})
    missing = [n for n in names if n not in effect.params]
    if extra or missing:
        raise ValueError(
            f"effect {effect.name}: give its parameters {names} (optional 'order'), or FMU "
            f"parameters of its block; missing {missing}, unknown {extra}"
        )
    order = effect.params.get("order")
    context = {k: order if order else v for k, v in DEFAULT_CONTEXT.items()}
    values = np.array([effect.params[n] for n in names])
    return hypothesis.to_plant(values, nominal, context)


def check_machine(
    model: str,
    parameters: dict[str, float],
    set_by: dict[str, str],
) -> None:
    """Refuse the virtual machine's plant parameters the FMU would refuse, before it runs.

    Parameters
    ----------
    model
        The plant model (its variable table and card).
    parameters
        The plant's parameter values (SI units).
    set_by
        Parameter -> the option that set it (``--effect ...``, ``--perturb ...``).

    Raises
    ------
    ValueError
        Naming the option, the parameter, its value and the range, or the constraint of the
        card it breaks with the options that set its values.
    """
    from twin_cosim.scenario.plant_parameters import range_problem

    card = plant_model(model)
    for name, option in set_by.items():
        problem = range_problem(card.parameters[name], parameters[name])
        if problem:
            raise ValueError(f"{option}: sets {name}: {problem}")
    broken = card.broken_constraints(parameters)
    if broken:
        text, names = broken[0]
        options = sorted({set_by[n] for n in names if n in set_by})
        raise ValueError(
            f"{', '.join(options) or 'the scenario'}: the plant would break {text}; the FMU of "
            f"{model} refuses it (models/{model}/card.yaml, constraints)"
        )


@dataclass
class Synthesis:
    """A synthetic measured run (the columns of a measured-run CSV, :mod:`twin_cosim.measured`)
    and its known answer."""

    run: RunRecord
    truth: dict[str, Any] = field(default_factory=dict)


def synthesize(
    scenario: Scenario,
    effects: list[EffectSpec],
    perturb: float = 0.0,
    seed: int = 0,
    fmu: Path | None = None,
    noise_position: float = 20e-9,
    noise_current: float = 5e-3,
) -> Synthesis:
    """Run the virtual machine.

    Parameters
    ----------
    scenario
        Reference, controller and nominal plant.
    effects
        Effects to switch on.
    perturb
        Largest relative calibration error of the calibrated parameters.
    seed
        Seed of the calibration error and the noise.
    fmu
        Plant FMU (the scenario's when None).
    noise_position, noise_current
        Standard deviations of the white measurement noise, m and A.
    """
    if not 0.0 <= perturb < 1.0:
        raise ValueError(f"--perturb must lie in [0, 1), got {perturb}")
    if noise_position < 0 or noise_current < 0:
        raise ValueError("noise standard deviations must be >= 0")
    rng = np.random.default_rng(seed)
    with Plant(scenario.plant_fmu(fmu)) as plant:
        nominal = {**plant.start_values(), **scenario.plant_parameters}
        model = plant.description.coSimulation.modelIdentifier
        calibrated = plant_model(model).calibrated if model in model_names() else ()
        factors = {name: 1.0 + rng.uniform(-perturb, perturb) for name in calibrated}
        parameters = {**nominal, **{k: nominal[k] * f for k, f in factors.items()}}
        set_by = {name: f"--perturb {perturb:g}" for name in factors if perturb > 0}
        fmu_parameters = set(plant.parameter_names())
        for effect in effects:
            overrides = effect_overrides(effect, parameters, fmu_parameters, model)
            parameters |= overrides
            set_by |= dict.fromkeys(overrides, effect.option)
        if model in model_names():
            check_machine(model, parameters, set_by)
        record = run_scenario(plant, scenario, plant_overrides=parameters)
    n = len(record)
    x = record["x"] + rng.normal(0.0, noise_position, n)
    resolution = parameters.get("position_resolution", 0.0)
    if resolution > 0:  # the noise is jitter before the encoder: its readings stay on the grid
        x = resolution * np.round(x / resolution)
    run = RunRecord.from_columns(
        {
            "t": record["t"],
            "x_ref": record["x_ref"],
            "x": x,
            "current": record["current"] + rng.normal(0.0, noise_current, n),
            "motor_speed": record["motor_speed"],
        },
        record.units,
    )
    truth = {
        "scenario": str(scenario.source),
        "effects": [{"name": e.name, "params": e.params} for e in effects],
        "perturb": perturb,
        "calibration_factors": factors,
        "seed": seed,
        "noise_position_m": noise_position,
        "noise_current_A": noise_current,
        "plant_parameters": {k: v for k, v in parameters.items() if nominal.get(k) != v},
    }
    return Synthesis(run, truth)


# ---- Random excitations: trajectories of the kind a user writes --------------------------------

EXCITATION_TRAVEL = 0.1  # m: the carriage stays within half of it either side of the start
EXCITATION_SAMPLE_PERIOD = 0.004  # s: the interpolator's input period
SPEED_RANGE = (8e-3, 0.6)  # m/s, and a fraction of the axis' speed limit: moves and ramps
CREEP_RANGE = (4e-3, 8e-3)  # m/s: creeps, the slowest steady motion a replay can follow
ACCELERATION_RANGE = (0.05, 0.75)  # m/s^2, and a fraction of the axis' acceleration limit
DWELL_RANGE = (0.1, 0.4)  # s
HOLD_RANGE = (0.15, 0.4)  # s at a constant speed of a ramp
MOVE_RANGE = (2e-3, 40e-3)  # m: a move's length
CREEP_LENGTH = (1e-3, 8e-3)  # m: a creep's length
OSCILLATION_AMPLITUDE = (0.5e-3, 15e-3)  # m, peak to peak
GESTURES = ("ramps", "move", "creep", "oscillation")
EXTRA_GESTURES = 1  # at most, drawn beside one of each kind in each half
CHANGE_SECONDS = 0.6  # s: the longest speed change (the acceleration drawn is raised to keep it)
GESTURE_SECONDS = 1.2  # s: the longest move or creep, and the longest oscillation cycle
ATTEMPTS = 50  # drafts of a half before the generator gives up (none has needed more than a few)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """A value drawn log-uniformly from [low, high]."""
    return float(np.exp(rng.uniform(np.log(low), np.log(high))))


def _round_up(value: float, digits: int = 3) -> float:
    """``value`` rounded up to ``digits`` decimals (a segment's duration must cover its ramp)."""
    scale = 10.0**digits
    return math.ceil(value * scale - 1e-9) / scale


def _gesture(
    kind: str, direction: float, x0: float, rng: np.random.Generator, limits: AxisLimits
) -> list[Segment]:
    """Segments of one gesture from rest at ``x0`` (m) to rest, starting in ``direction``;
    each speed change takes at most :data:`CHANGE_SECONDS`, a move or a creep at most
    :data:`GESTURE_SECONDS`."""
    v_top, a_top = SPEED_RANGE[1] * limits.velocity, ACCELERATION_RANGE[1] * limits.acceleration

    def speed() -> float:
        return round(_log_uniform(rng, SPEED_RANGE[0], v_top), 4)

    def acceleration(change: float) -> float:
        drawn = _log_uniform(rng, ACCELERATION_RANGE[0], a_top)
        return round(min(max(drawn, abs(change) / CHANGE_SECONDS), a_top), 3)

    if kind in ("move", "creep"):
        v = speed() if kind == "move" else round(_log_uniform(rng, *CREEP_RANGE), 5)
        lengths = MOVE_RANGE if kind == "move" else CREEP_LENGTH
        length = min(_log_uniform(rng, *lengths), v * GESTURE_SECONDS)
        return [Move(round(x0 + direction * length, 6), v, acceleration(v))]
    if kind == "oscillation":
        amplitude = _log_uniform(rng, *OSCILLATION_AMPLITUDE)
        v, a = speed(), acceleration(0.0)
        frequency = min(v / (math.pi * amplitude), math.sqrt(a / (2.0 * math.pi**2 * amplitude)))
        frequency = max(frequency, 1.0 / GESTURE_SECONDS)
        cycles = int(rng.integers(1, 3))
        return [Oscillation(round(direction * amplitude, 5), round(frequency, 3), cycles)]
    levels = [direction * speed()]  # ramps: speed levels, the sign changing while moving
    for _ in range(int(rng.integers(1, 3))):
        levels.append(-levels[-1] if rng.uniform() < 0.6 else math.copysign(speed(), levels[-1]))
    if all(math.copysign(1.0, v) == direction for v in levels):
        levels[-1] = -levels[-1]
    segments, v0 = [], 0.0
    for level in [*levels, 0.0]:
        a = acceleration(level - v0)
        hold = 0.0 if level == 0.0 else rng.uniform(*HOLD_RANGE)
        segments.append(Ramp(level, a, _round_up(abs(level - v0) / a + hold)))
        v0 = level
    return segments


def _mirrored(segments: list[Segment], x0: float) -> list[Segment]:
    """The gesture the other way round from ``x0`` (m)."""
    mirrored: list[Segment] = []
    for s in segments:
        if isinstance(s, Move):
            mirrored.append(Move(2.0 * x0 - s.to, s.velocity, s.acceleration))
        elif isinstance(s, Oscillation):
            mirrored.append(Oscillation(-s.amplitude, s.frequency, s.cycles))
        elif isinstance(s, Ramp):
            mirrored.append(Ramp(-s.velocity, s.acceleration, s.duration))
        else:
            mirrored.append(s)
    return mirrored


def _half(rng: np.random.Generator, x0: float, limits: AxisLimits) -> tuple[list[Segment], float]:
    """One half of an excitation from rest at ``x0`` (m): a dwell, then one gesture of each kind
    and up to :data:`EXTRA_GESTURES` more in a random order, each followed by a dwell, every
    position inside the travel; and the position where it ends (m)."""
    kinds = list(GESTURES) + list(
        rng.choice(GESTURES, size=int(rng.integers(0, EXTRA_GESTURES + 1)))
    )
    rng.shuffle(kinds)
    half: list[Segment] = [Dwell(round(rng.uniform(*DWELL_RANGE), 3))]
    edge = EXCITATION_TRAVEL / 2.0
    for kind in kinds:
        direction = 1.0 if rng.uniform() < 0.5 else -1.0
        gesture = _gesture(kind, direction, x0, rng, limits)
        for draft in (gesture, _mirrored(gesture, x0)):
            path = sample_segments(draft, EXCITATION_SAMPLE_PERIOD, x0)
            if np.all(np.abs(path) <= edge):
                half += [*draft, Dwell(round(rng.uniform(*DWELL_RANGE), 3))]
                x0 = float(path[-1])
                break
    return half, x0


def covers_regimes(reference: ReferenceGrid, split: float = 0.5) -> bool:
    """Whether each part of a time split of the reference at ``split`` holds every regime of
    :data:`~twin_cosim.gap.data.regimes.REGIMES` (standstill, breakaway, acceleration,
    constant velocity, reversal) and strokes in both directions."""
    t = reference.time
    labels = classify_regimes(t, reference.velocity, reference.acceleration)
    direction = np.where(labels == STANDSTILL, 0.0, np.sign(reference.velocity))
    cut = t <= split * t[-1]
    for part in (cut, ~cut):
        found = set(np.unique(labels[part]).tolist())
        ways = {d for _, _, d in strokes(direction[part], reference.position[part])}
        if found != set(range(len(REGIMES))) or ways != {-1, 1}:
            return False
    return True


def random_excitation(seed: int, limits: AxisLimits = DEFAULT_LIMITS) -> list[Segment]:
    """A seeded random excitation of the kind a user writes, for a time split at the midpoint.

    Two halves of equal length, drawn apart (they differ), each a dwell and then a move, a
    creep, speed levels changing sign while moving (ramps), a cosine oscillation, and perhaps
    one more of these, in a random order and directions, with dwells between: moves of 2-40 mm at
    8 mm/s to 60 % of the axis' speed limit, creeps of 1-8 mm at 4-8 mm/s (each at most 1.2 s
    long), accelerations of 0.05 m/s^2 to 75 % of the axis' limit (raised where a speed
    change would take over 0.6 s), oscillations of 0.5-15 mm within those speeds and
    accelerations, dwells of 0.1-0.4 s; sizes and speeds log-uniform, every position within
    +/- 50 mm of the start (a gesture that would leave that goes the other way, or is left
    out). A half is drawn again until each half covers every regime a diagnosis needs
    (:func:`covers_regimes`, on the interpolated reference).

    Nothing moves steadily below 4 mm/s: there the Fine-Tune loop sticks and slips with
    Stribeck friction of the library's sizes (0.1-0.3 N.m), and the stick-slip's phase hangs
    on every parameter (a 1 % change of the torque constant moves the position by 2-5 um RMS
    over a creep at 0.5-2 mm/s, against 0.03 um at 8 mm/s and above): a replay cannot follow
    it sample by sample, so no diagnosis that compares replays with measurements can (docs/gap.md).

    Parameters
    ----------
    seed
        Seed of the draws.
    limits
        The axis' speed (m/s) and acceleration (m/s^2) limits.

    Raises
    ------
    RuntimeError
        When no draft covers the regimes in :data:`ATTEMPTS` tries.
    """
    rng = np.random.default_rng([2203, seed])
    for _ in range(ATTEMPTS):
        first, x_mid = _half(rng, 0.0, limits)
        second, _ = _half(rng, x_mid, limits)
        lengths = [segments_duration(first), segments_duration(second, x_mid)]
        pad = round(abs(lengths[0] - lengths[1]), 3)
        if pad > 0:
            (first if lengths[0] < lengths[1] else second).append(Dwell(pad))
        segments = first + second
        samples = sample_segments(segments, EXCITATION_SAMPLE_PERIOD)
        grid = interpolate(samples, EXCITATION_SAMPLE_PERIOD, ControllerSettings().position_period)
        if covers_regimes(grid):
            return segments
    raise RuntimeError(f"random excitation {seed}: no draft covered every regime")


def segment_yaml(segment: Segment) -> dict[str, Any]:
    """A segment as the ``reference.segments`` item of a scenario file."""
    if isinstance(segment, Dwell):
        return {"dwell": segment.duration}
    kind = type(segment).__name__.lower()
    return {kind: dataclasses.asdict(segment)}


def write_excitation_scenario(scenario_file: Path, seed: int, out: Path) -> Path:
    """Write ``out``: the scenario file with its reference replaced by the random excitation of
    ``seed`` (:func:`random_excitation`, within the default axis limits); its plant and
    controller are the scenario's (relative paths rewritten for the new folder)."""
    data = load_yaml(scenario_file)
    reference = {
        "sample_period": EXCITATION_SAMPLE_PERIOD,
        "start_position": 0.0,
        "segments": [segment_yaml(s) for s in random_excitation(seed)],
    }
    relocate_paths(data, scenario_file.parent, out.parent)
    data.update(
        name=f"random-excitation-{seed}",
        description=f"random excitation {seed} (twin synth --random-excitation) with the plant and "
        f"controller of {scenario_file.name}",
        reference=reference,
        run={**(data.get("run") or {}), "metrics_window": [0.0, None]},
    )
    out.write_text(dump_yaml(data))
    return out
