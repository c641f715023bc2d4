"""Tuning for contours: the objective of a machine's campaign and its ``optimize`` section.

A candidate is every axis' six parameters, [X.Kp_pos, ..., X.f_H, Y.Kp_pos, ..., Y.f_H]. Its
cases are circles (a grid of radii x feeds x directions) or a part program; on each case the
machine runs in lockstep and the case's value (um) is

- ``G``: the circular deviation (ISO 230-4) of a circle;
- ``spike``: the largest reversal spike |height| of a circle;
- ``contour``: the largest contour error of the run (circle or program).

The fitness is the worst case's value, each optionally relative (``relative: true``: times the
first case's reference value over this case's, the reference being the scenario's own sets,
Fine-Tune by default), plus the penalty when an axis' IAU exceeds the cap times its IAU in the
reference run of that case (a cap per axis), twice the penalty when a run fails or leaves the
error band. A task's cutoff stops a candidate after the first case above it (exact for the
worst case; CE's elite cutoff, :mod:`twin_cosim.optimize.early_stop`).

The machine scenario's ``optimize`` section::

    optimize:
      target: G                   # G | spike | contour
      relative: true              # score each case against the reference sets on it
      circles: {radii_mm: [5, 10, 25], feeds_mm_min: [500, 1000, 2000], directions: [ccw]}
      bounds: {Kp_pos: [20, 150], ...}    # per parameter, for every axis (the single-axis
      iau_cap: 1.05                       # defaults of twin_cosim.optimize.config)
      abort_error_um: 1000
      penalty_um: 1.0e6
      methods: {ce: {...}}
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, run_circle
from twin_cosim.contour.gcode import Program
from twin_cosim.contour.machine_run import (
    MachinePlants,
    MachineRecord,
    contour_metrics,
    run_program,
)
from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.cosim import RunAborted
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.config import DEFAULT_BOUNDS, OptimizeConfig
from twin_cosim.optimize.early_stop import OwnEvaluations, lower_bound_above
from twin_cosim.optimize.objective import EvaluationTask, evaluation_result
from twin_cosim.plant import PlantError
from twin_cosim.scenario.machine import MachineScenario
from twin_cosim.schema import Checker

TARGETS = ("G", "spike", "contour")
KEYS = {"target", "relative", "circles", "bounds", "iau_cap", "abort_error_um", "penalty_um"}
KEYS |= {"methods"}
GRID_DEFAULT = {"radii_mm": [10.0], "feeds_mm_min": [1000.0], "directions": ["ccw"]}


@dataclass(frozen=True)
class ContourSettings:
    """The checked ``optimize`` section of a machine scenario.

    Attributes
    ----------
    target : str
        ``G``, ``spike`` or ``contour``.
    relative : bool
        Score each case against the reference sets' value on it.
    circles : tuple of CircleSpec
        The grid of circles (radius m, feed m/s, direction).
    config : OptimizeConfig
        Bounds of every axis' parameters (named ``X.Kp_pos``, ...), IAU cap, error band,
        penalty and method settings.
    """

    target: str
    relative: bool
    circles: tuple[CircleSpec, ...]
    config: OptimizeConfig


def contour_settings(machine: MachineScenario, target: str | None = None) -> ContourSettings:
    """Check the machine's ``optimize`` section; ``target`` (command line) wins over its own.

    Raises
    ------
    ScenarioError
        Naming the file and the key.
    """
    check = Checker(machine.source)
    data = check.mapping(machine.optimize, "optimize", KEYS)
    chosen = target or data.get("target", "G")
    if chosen not in TARGETS:
        raise check.fail("optimize.target", f"one of {list(TARGETS)}", chosen)
    relative = data.get("relative", True)
    if not isinstance(relative, bool):
        raise check.fail("optimize.relative", "true or false", relative)
    grid = {
        **GRID_DEFAULT,
        **check.mapping(data.get("circles"), "optimize.circles", set(GRID_DEFAULT)),
    }
    for key in ("radii_mm", "feeds_mm_min"):
        if not isinstance(grid[key], list) or not grid[key]:
            raise check.fail(f"optimize.circles.{key}", "a non-empty list of numbers", grid[key])
    radii = [check.number(r, "optimize.circles.radii_mm", positive=True) for r in grid["radii_mm"]]
    feeds = [
        check.number(f, "optimize.circles.feeds_mm_min", positive=True)
        for f in grid["feeds_mm_min"]
    ]
    directions = check.names(grid["directions"], "optimize.circles.directions")
    if not directions or not set(directions) <= {"cw", "ccw"}:
        raise check.fail("optimize.circles.directions", "a list of cw, ccw", directions)
    circles = tuple(
        CircleSpec(r * 1e-3, f * MM_PER_MIN, d) for r in radii for f in feeds for d in directions
    )
    return ContourSettings(chosen, relative, circles, _config(check, data, machine))


def _config(check: Checker, data: dict[str, Any], machine: MachineScenario) -> OptimizeConfig:
    """Bounds of every axis' six parameters and the campaign's limits."""
    bounds = dict(DEFAULT_BOUNDS)
    for name, pair in check.mapping(
        data.get("bounds"), "optimize.bounds", set(TUNED_NAMES)
    ).items():
        if not (isinstance(pair, list) and len(pair) == 2):
            raise check.fail(f"optimize.bounds.{name}", "[low, high]", pair)
        low = check.number(pair[0], f"optimize.bounds.{name}[0]", minimum=0.0)
        high = check.number(pair[1], f"optimize.bounds.{name}[1]")
        if not low < high or (name in ("Kp_pos", "Kp_vel", "PP3") and low <= 0):
            raise check.fail(f"optimize.bounds.{name}", "0 <= low < high (low > 0 for gains)", pair)
        bounds[name] = (low, high)
    names = tuple(f"{a}.{n}" for a in machine.axis_names for n in TUNED_NAMES)
    iau_cap = data.get("iau_cap", 1.05)
    return OptimizeConfig(
        lower=np.array([bounds[n.split(".")[1]][0] for n in names]),
        upper=np.array([bounds[n.split(".")[1]][1] for n in names]),
        window=(0.0, None),
        iau_cap=None
        if iau_cap is None
        else check.number(iau_cap, "optimize.iau_cap", positive=True),
        abort_error_um=check.number(
            data.get("abort_error_um", 1000.0), "optimize.abort_error_um", positive=True
        ),
        penalty_um=check.number(
            data.get("penalty_um", 1.0e6), "optimize.penalty_um", positive=True
        ),
        methods=check.mapping(data.get("methods"), "optimize.methods"),
        tuned_names=names,
    )


def axes_tuned(machine: MachineScenario, x: np.ndarray) -> dict[str, TunedParameters]:
    """Each axis' parameters from a candidate (ValueError on a set the controller refuses)."""
    n = len(TUNED_NAMES)
    return {
        name: TunedParameters.from_array(x[k * n : (k + 1) * n])
        for k, name in enumerate(machine.axis_names)
    }


def machine_vector(machine: MachineScenario) -> np.ndarray:
    """The machine's own sets as a candidate."""
    return np.concatenate([axis.tuned.as_array() for axis in machine.axes])


@dataclass(frozen=True)
class Case:
    """One run of a candidate: a circle, or a part program (``label`` names it)."""

    label: str
    circle: CircleSpec | None = None
    program: Program | None = None


def cases_of(settings: ContourSettings, program: Program | None) -> tuple[Case, ...]:
    """The program as the only case, else the circles of the grid."""
    if program is not None:
        return (Case(Path(program.source).name, program=program),)
    return tuple(
        Case(f"R{c.radius * 1e3:g}mm-F{c.feed / MM_PER_MIN:g}-{c.direction}", circle=c)
        for c in settings.circles
    )


def case_values(
    machine: MachineScenario, plants: MachinePlants, case: Case, abort_error: float
) -> dict[str, Any]:
    """Run one case: its G, largest spike and contour error (um), each axis' IAU (A.s)."""
    if case.circle is not None:
        run = run_circle(machine, plants, case.circle, abort_error=abort_error)
        record: MachineRecord = run.record
        values = {
            "G": run.result.G_um,
            "spike": max(abs(s.height_um) for s in run.result.spikes),
        }
    else:
        record = run_program(machine, case.program, plants, abort_error=abort_error)[0]
        values = {}
    values["contour"] = contour_metrics(record)["contour_error_max_um"]
    values["IAU"] = {name: compute_metrics(frame).IAU for name, frame in record.axes.items()}
    ratio = machine.axes[0].settings.speed_steps_per_position_step
    values["steps"] = sum(len(f) for f in record.axes.values()) * ratio
    return values


@dataclass(frozen=True)
class ContourObjectiveSpec:
    """What a worker builds the objective from (picklable: resolved values only).

    Attributes
    ----------
    machine : MachineScenario
        The machine.
    settings : ContourSettings
        Target, circles and limits.
    cases : tuple of Case
        The runs of every candidate.
    references : tuple of dict
        Per case: the reference sets' values (``G``, ``spike``, ``contour`` um, ``IAU`` A.s
        per axis), for the IAU caps and the relative scales; empty for the reference runs.
    """

    machine: MachineScenario
    settings: ContourSettings
    cases: tuple[Case, ...]
    references: tuple[dict[str, Any], ...] = ()

    def build(self) -> ContourObjective:
        """The objective (a worker of :mod:`twin_cosim.workers`)."""
        return ContourObjective(self)


class ContourObjective:
    """Scores candidates on one set of plant instances (one per axis, reset per run)."""

    def __init__(self, spec: ContourObjectiveSpec) -> None:
        self.spec = spec
        self.plants = MachinePlants(spec.machine)
        self._order = list(range(len(spec.cases)))
        self._own = OwnEvaluations()

    def reference_values(self) -> list[dict[str, Any]]:
        """Each case's values with the machine's own sets (the reference)."""
        machine = self.spec.machine
        return [case_values(machine, self.plants, case, math.inf) for case in self.spec.cases]

    def __call__(self, task: EvaluationTask | np.ndarray) -> dict[str, Any]:
        """Evaluate one candidate (an EvaluationTask, its cutoff lowered by this worker's own
        complete evaluations of its generation, or a vector of every axis' parameters).

        Returns
        -------
        dict
            ``fitness`` (um), ``status`` (ok, violation, unstable, failed, stopped),
            ``reason``, ``metrics`` (the worst case's target value and per case the values) and
            ``steps`` (speed-loop steps simulated, all axes).
        """
        return self._own.evaluate(task, self._evaluate)

    def _evaluate(self, x: np.ndarray, cutoff: float) -> dict[str, Any]:
        """The result of :meth:`__call__` for ``x`` with cutoff ``cutoff`` (um)."""
        settings = self.spec.settings
        config = settings.config
        failure = 2.0 * config.penalty_um
        try:
            machine = self.spec.machine.with_tuned(axes_tuned(self.spec.machine, np.asarray(x)))
        except ValueError as exc:
            return evaluation_result(failure, "failed", str(exc), None, 0)
        scores: dict[int, float] = {}
        runs: dict[int, dict[str, Any]] = {}
        steps = 0
        for i in list(self._order):
            case = self.spec.cases[i]
            try:
                values = case_values(machine, self.plants, case, config.abort_error_um * 1e-6)
            except RunAborted as exc:
                return evaluation_result(failure, "unstable", f"{case.label}: {exc}", None, steps)
            except PlantError as exc:
                return evaluation_result(failure, "failed", f"{case.label}: {exc}", None, steps)
            steps += values.pop("steps")
            scores[i], status, reason = self._score(i, values)
            runs[i] = {"case": case.label, "status": status, "reason": reason, **values}
            worst = max(scores.values())
            if worst > cutoff and len(scores) < len(self.spec.cases):
                self._put_first(i)
                reason = f"{case.label}: fitness at least {worst:.6g} um, above the cutoff"
                return evaluation_result(lower_bound_above(cutoff), "stopped", reason, None, steps)
        ordered = [runs[i] for i in range(len(runs))]
        worst_case = max(range(len(ordered)), key=lambda i: scores[i])
        self._put_first(worst_case)
        status = "ok" if all(r["status"] == "ok" for r in ordered) else "violation"
        reason = "; ".join(r["reason"] for r in ordered if r["reason"])
        metrics = {
            settings.target: max(r[settings.target] for r in ordered),
            "worst_case": ordered[worst_case]["case"],
            "runs": ordered,
        }
        return evaluation_result(scores[worst_case], status, reason, metrics, steps)

    def _score(self, i: int, values: dict[str, Any]) -> tuple[float, str, str]:
        """Fitness (um), status and reason of case ``i``'s values."""
        settings = self.spec.settings
        reference = self.spec.references[i]
        scale = 1.0
        if settings.relative:
            scale = self.spec.references[0][settings.target] / reference[settings.target]
        score = scale * values[settings.target]
        cap = settings.config.iau_cap
        if cap is not None:
            over = [
                f"axis {name}: IAU {iau:.4g} A.s above the cap {cap * reference['IAU'][name]:.4g}"
                for name, iau in values["IAU"].items()
                if iau > cap * reference["IAU"][name]
            ]
            if over:
                return settings.config.penalty_um + score, "violation", "; ".join(over)
        return score, "ok", ""

    def _put_first(self, case: int) -> None:
        self._order.remove(case)
        self._order.insert(0, case)

    def close(self) -> None:
        """Free the plants."""
        self.plants.close()
