"""The virtual machine in production: the twin with hidden effects, calibration error, noise and
drift, running the scenario's reference again and again, one trace window per run.

The machine is drawn once: each calibrated parameter of the plant model (its card's
``calibrated``) multiplied by (1 + u), u uniform in [-perturb, perturb], and the ``--effect``
effects switched on (:mod:`twin_cosim.gap.synth`). Window w then runs with each drift added:
``NAME:param=RATE`` grows the effect's parameter (as ``twin synth --effect`` names it: a
hypothesis parameter such as ``coulomb_change:delta_coulomb``, or ``plant:NAME`` for an FMU
parameter) by RATE per window from window ``drift_start`` on, so that window ``drift_start``
has one step of it, window ``drift_start + 1`` two, and so on. Each window has its own draw of
white measurement noise (:func:`twin_cosim.gap.synth.synthesize`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from twin_cosim.gap.synth import EffectSpec, effect_overrides, parse_effect, synthesize
from twin_cosim.plant import Plant
from twin_cosim.plant_model import model_names, plant_model
from twin_cosim.runtime.opcua import Window
from twin_cosim.scenario import Scenario


@dataclass(frozen=True)
class Drift:
    """An effect parameter that grows by ``rate`` (its unit) per window."""

    effect: str
    parameter: str
    rate: float


def parse_drift(text: str) -> Drift:
    """``NAME:param=RATE_PER_WINDOW`` (one parameter); ValueError says what was expected."""
    spec = parse_effect(text)
    if len(spec.params) != 1:
        raise ValueError(f"--drift {text!r}: give one param=RATE_PER_WINDOW after '{spec.name}:'")
    ((parameter, rate),) = spec.params.items()
    return Drift(spec.name, parameter, rate)


@dataclass(frozen=True)
class VirtualMachine:
    """A machine drawn once, whose windows differ by their noise and the drifts.

    Attributes
    ----------
    scenario : Scenario
        The cycle (its reference) and the controller.
    fmu : str
        The plant FMU.
    model : str
        Its plant model.
    base : dict
        The machine's FMU parameters with the calibration error, before any effect.
    effects : list of EffectSpec
        The effects switched on.
    drifts : list of Drift
        What grows per window, from window ``drift_start`` on.
    drift_start : int
        The first window with a step of drift.
    seed : int
        Seed of the calibration error; window w's noise has seed ``seed + 1 + w``.
    noise_position, noise_current : float
        White measurement noise, m and A (standard deviations).
    factors : dict
        The calibration error: each calibrated parameter's factor.
    fmu_parameters : frozenset
        The FMU's parameter names.
    """

    scenario: Scenario
    fmu: str
    model: str
    base: dict[str, float]
    effects: list[EffectSpec]
    drifts: list[Drift]
    drift_start: int
    seed: int
    noise_position: float
    noise_current: float
    factors: dict[str, float]
    fmu_parameters: frozenset[str]

    def parameters_at(self, window: int) -> dict[str, float]:
        """The machine's FMU parameters in ``window``: the effects, each drifted parameter
        grown by its steps so far.

        Raises
        ------
        ValueError
            For a drift of a parameter its effect does not have.
        """
        steps = max(0, window - self.drift_start + 1)
        given = {e.name for e in self.effects}
        specs = list(self.effects)
        for drift in self.drifts:
            if drift.effect not in given:
                start = {drift.parameter: self.base.get(drift.parameter, 0.0)}
                specs.append(EffectSpec(drift.effect, start if drift.effect == "plant" else {}))
                given.add(drift.effect)
        parameters = dict(self.base)
        for spec in specs:
            params = dict(spec.params)
            if spec.name != "plant" and not set(params) <= self.fmu_parameters - {"order"}:
                params = {**_initial_values(spec.name, self.model), **params}
            elif spec.name != "plant" and not params:
                params = _initial_values(spec.name, self.model)
            for drift in (d for d in self.drifts if d.effect == spec.name):
                if drift.parameter not in params:
                    raise ValueError(
                        f"--drift {drift.effect}:{drift.parameter}=...: {drift.effect} has no "
                        f"parameter {drift.parameter!r} (expected one of {sorted(params)})"
                    )
                params[drift.parameter] += drift.rate * steps
            parameters |= effect_overrides(
                EffectSpec(spec.name, params), parameters, set(self.fmu_parameters), self.model
            )
        return parameters

    def window(self, window: int) -> Window:
        """Run window ``window`` of the machine: its trace at the position-loop period, with
        ``Sequence`` window + 1."""
        scenario = dataclasses.replace(
            self.scenario,
            plant_parameters={**self.scenario.plant_parameters, **self.parameters_at(window)},
        )
        run = synthesize(
            scenario,
            [],
            0.0,
            self.seed + 1 + window,
            self.fmu,
            self.noise_position,
            self.noise_current,
        ).run
        return Window(
            window + 1, run["t"], run["x_ref"], run["x"], run["current"], run["motor_speed"]
        )


def _initial_values(effect: str, model: str) -> dict[str, float]:
    """An effect's hypothesis parameters at their start values."""
    hypothesis = next(h for h in plant_model(model).hypotheses if h.name == effect)
    return {p.name: p.initial for p in hypothesis.parameters}


def draw_machine(
    scenario: Scenario,
    fmu: str,
    effects: list[EffectSpec],
    drifts: list[Drift],
    drift_start: int = 0,
    perturb: float = 0.0,
    seed: int = 0,
    noise_position: float = 20e-9,
    noise_current: float = 5e-3,
) -> VirtualMachine:
    """Draw the machine: calibration error (seeded) under the scenario's plant, its effects and
    drifts checked.

    Raises
    ------
    ValueError
        On a perturbation outside [0, 1), negative noise, or an effect or drift the plant
        model does not have.
    """
    if not 0.0 <= perturb < 1.0:
        raise ValueError(f"--perturb must lie in [0, 1), got {perturb}")
    if noise_position < 0 or noise_current < 0:
        raise ValueError("noise standard deviations must be >= 0")
    if drift_start < 0:
        raise ValueError(f"--drift-start must be >= 0, got {drift_start}")
    rng = np.random.default_rng(seed)
    with Plant(fmu) as plant:
        model = plant.description.coSimulation.modelIdentifier
        nominal = {**plant.start_values(), **scenario.plant_parameters}
        fmu_parameters = frozenset(plant.parameter_names())
    calibrated = plant_model(model).calibrated if model in model_names() else ()
    factors = {name: 1.0 + rng.uniform(-perturb, perturb) for name in calibrated}
    machine = VirtualMachine(
        scenario,
        fmu,
        model,
        {**nominal, **{k: nominal[k] * f for k, f in factors.items()}},
        list(effects),
        list(drifts),
        drift_start,
        seed,
        noise_position,
        noise_current,
        factors,
        fmu_parameters,
    )
    machine.parameters_at(drift_start)  # every effect and drift checked now
    return machine
