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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.context import DEFAULT_CONTEXT, library_for
from twin_cosim.plant import Plant
from twin_cosim.plant_model import model_names, plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario


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
    from twin_cosim.scenario.plant_file import range_problem

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
