"""The objective of eq. (12): one closed-loop run per candidate K, scored by E_pk.

A candidate's fitness (um) is

- E_pk over the objective window when the run is valid;
- penalty + E_pk when it violates the control-effort cap (IAU above the limit);
- 2 x penalty when it fails: parameters the controller refuses, a run stopped because the error
  left the allowed band (unstable loop), or an FMU error. The reason is kept with the result.

Robust objective: with several scenarios and plant samples (relative factors on plant
parameters, the first sample the nominal plant), every candidate runs on each scenario x sample;
each run is scored as above (each scenario with its own IAU limit) and the fitness is the worst
(or the mean) of the runs.

A task may carry a cutoff (:class:`EvaluationTask`): when the candidate's fitness is certain to
exceed it, the runs stop early and the result has status ``stopped`` with a lower bound as
fitness (see :mod:`twin_cosim.optimize.early_stop`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.controller import TunedParameters
from twin_cosim.cosim import RunAborted, run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.config import OptimizeConfig, load_config
from twin_cosim.optimize.early_stop import lower_bound_above, window_spans_run
from twin_cosim.plant import Plant, PlantError
from twin_cosim.plant_parameters import with_plant_parameters
from twin_cosim.scenario import Scenario, load_scenario

AGGREGATES = ("worst", "mean")


@dataclass(frozen=True)
class EvaluationTask:
    """A candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] and the cutoff (um) of its fitness."""

    x: np.ndarray
    cutoff_um: float = math.inf


@dataclass(frozen=True)
class ObjectiveSpec:
    """Everything a worker needs to build the objective (picklable: paths and numbers only).

    Attributes
    ----------
    scenario : str
        Scenario file (its ``optimize`` section configures the objective).
    fmu : str or None
        Plant FMU; the scenario's (or the project's drive2mass) when None.
    iau_limit : float or None
        Largest allowed IAU on ``scenario``, A.s; None: no cap.
    plant_parameters : str or None
        Plant parameter file applied to every scenario.
    scenarios : tuple of str
        Further scenarios of a robust objective.
    iau_limits : tuple
        Their IAU limits, A.s (None: no cap).
    samples : tuple of dict
        Plant samples: relative factors by FMU parameter name; none: the nominal plant only.
    aggregate : str
        ``worst`` or ``mean`` over the runs.
    """

    scenario: str
    fmu: str | None
    iau_limit: float | None
    plant_parameters: str | None = None
    scenarios: tuple[str, ...] = ()
    iau_limits: tuple[float | None, ...] = ()
    samples: tuple[dict[str, float], ...] = ()
    aggregate: str = "worst"

    def build(self) -> Objective:
        """The objective (a worker of :mod:`twin_cosim.workers`)."""
        return Objective(self)


@dataclass(frozen=True)
class _Case:
    """One run of a candidate: a scenario, a plant sample, its IAU limit."""

    label: str
    scenario: Scenario
    window: tuple[float, float | None]
    overrides: dict[str, float]
    iau_limit: float | None
    steps: int


class Objective:
    """Scores candidates on one plant instance (extracted and instantiated once, reset per run)."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.spec = spec
        self.scenario: Scenario = self._load(spec.scenario)
        self.config: OptimizeConfig = load_config(self.scenario)
        fmu = Path(spec.fmu) if spec.fmu else self.scenario.fmu
        self.plant = Plant(fmu)
        start = self.plant.start_values()
        samples = spec.samples or ({},)
        files = (spec.scenario, *spec.scenarios)
        limits = (spec.iau_limit, *spec.iau_limits)
        self.cases: list[_Case] = []
        for file, limit in zip(files, limits, strict=True):
            scenario = self.scenario if file == spec.scenario else self._load(file)
            window = load_config(scenario).window
            nominal = {**start, **scenario.plant_parameters}
            ratio = scenario.settings.speed_steps_per_position_step
            for k, factors in enumerate(samples):
                overrides = {name: nominal[name] * f for name, f in factors.items()}
                label = scenario.name + (f"/sample{k}" if len(samples) > 1 else "")
                steps = len(scenario.reference.position) * ratio
                self.cases.append(_Case(label, scenario, window, overrides, limit, steps))
        self.exact_early_stop = all(
            window_spans_run(c.window, c.scenario.reference.duration) for c in self.cases
        )

    def _load(self, path: str) -> Scenario:
        return with_plant_parameters(load_scenario(path), self.spec.plant_parameters, self.spec.fmu)

    def __call__(self, task: np.ndarray | EvaluationTask) -> dict[str, Any]:
        """Evaluate one candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] (physical units).

        Returns
        -------
        dict
            ``fitness`` (um), ``status`` (ok, violation, unstable, failed, stopped), ``reason``,
            ``metrics`` (None when the run did not complete; with several runs the aggregate
            and ``runs``) and ``steps`` (speed-loop steps simulated).
        """
        x, cutoff = (
            (task.x, task.cutoff_um) if isinstance(task, EvaluationTask) else (task, math.inf)
        )
        if not self.exact_early_stop:
            cutoff = math.inf
        failure = 2.0 * self.config.penalty_um
        try:
            tuned = TunedParameters.from_array(x)
        except ValueError as exc:
            return _result(failure, "failed", str(exc), None, 0)
        n = len(self.cases)
        scores, runs, steps = [], [], 0
        for case in self.cases:
            allowed = cutoff if self.spec.aggregate == "worst" else n * cutoff - sum(scores)
            abort_um = min(self.config.abort_error_um, allowed)
            try:
                record = run_scenario(
                    self.plant,
                    case.scenario,
                    tuned,
                    plant_overrides=case.overrides,
                    abort_error=abort_um * 1e-6,
                )
            except RunAborted as exc:
                steps += _steps_until(case, exc.time_s)
                if abort_um < self.config.abort_error_um:
                    reason = f"{case.label}: {exc}; fitness above the cutoff {cutoff:.6g} um"
                    return _result(lower_bound_above(cutoff), "stopped", reason, None, steps)
                return _result(failure, "unstable", f"{case.label}: {exc}", None, steps)
            except PlantError as exc:
                return _result(failure, "failed", f"{case.label}: {exc}", None, steps)
            steps += case.steps
            metrics = compute_metrics(record, case.window).as_dict()
            score, status, reason = self._score(metrics, case.iau_limit)
            scores.append(score)
            runs.append({"case": case.label, "status": status, "reason": reason, **metrics})
            bound = max(scores) if self.spec.aggregate == "worst" else sum(scores) / n
            if bound > cutoff and len(scores) < n:
                reason = f"{case.label}: fitness at least {bound:.6g} um, above the cutoff"
                return _result(bound, "stopped", reason, None, steps)
        if n == 1:
            run = runs[0]
            metrics = {k: v for k, v in run.items() if k not in ("case", "status", "reason")}
            return _result(scores[0], run["status"], run["reason"], metrics, steps)
        combine = max if self.spec.aggregate == "worst" else (lambda v: sum(v) / len(v))
        worst = int(np.argmax(scores))
        metrics = {
            name: float(combine([r[name] for r in runs])) for name in ("E_pk_um", "ITAE", "IAU")
        }
        metrics["runs"] = runs
        status = "ok" if all(r["status"] == "ok" for r in runs) else "violation"
        reason = "; ".join(r["reason"] for r in runs if r["reason"])
        fitness = float(combine(scores))
        return _result(
            fitness, status, reason or f"worst run: {runs[worst]['case']}", metrics, steps
        )

    def _score(self, metrics: dict[str, float], limit: float | None) -> tuple[float, str, str]:
        """Fitness (um), status and reason of one completed run."""
        if limit is not None and metrics["IAU"] > limit:
            reason = f"IAU {metrics['IAU']:.4g} A.s above the cap {limit:.4g} A.s"
            return self.config.penalty_um + metrics["E_pk_um"], "violation", reason
        return metrics["E_pk_um"], "ok", ""

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def _steps_until(case: _Case, time_s: float) -> int:
    """Speed-loop steps simulated by a run stopped at position-loop time ``time_s``."""
    if not math.isfinite(time_s):
        return case.steps
    ratio = case.steps // len(case.scenario.reference.position)
    return int(round(time_s / case.scenario.reference.period)) * ratio


def _result(
    fitness: float, status: str, reason: str, metrics: dict[str, Any] | None, steps: int
) -> dict[str, Any]:
    return {
        "fitness": float(fitness),
        "status": status,
        "reason": reason,
        "metrics": metrics,
        "steps": steps,
    }
