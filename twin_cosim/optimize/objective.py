"""The objective of eq. (12) on a worker: one closed-loop run per candidate K and case, scored by
E_pk.

A candidate's fitness (um) is

- E_pk over the objective window when the run is valid, plus, with a settling weight w
  (``--objective settling=W``), w times the run's settling time in ms
  (:data:`twin_cosim.metrics.Metrics.settling_ms`: after each reversal or stop of the reference,
  the time until the error stays within 1 um); w = 0, the default, is the paper's objective;
- penalty + E_pk when it violates the control-effort cap (IAU above the limit);
- 2 x penalty when it fails: parameters the controller refuses, a run stopped because the error
  left the allowed band (unstable loop), a run that oscillates (a limit cycle or a chattering
  current, :mod:`twin_cosim.oscillation`; status ``unstable``), or an FMU error. The reason is
  kept with the result.

Robust objective: with several scenarios and plant samples (relative factors on plant
parameters, the first sample the nominal plant), every candidate runs on each scenario x sample
(a case); each run is scored as above, with the IAU limit of its own case (the cap times the
reference set's IAU on that scenario and plant sample), its E_pk optionally multiplied by the
case's scale (a relative objective: the first case's reference E_pk over this case's), and the
fitness is the worst (or the mean) of the runs.

A task may carry a cutoff (:class:`~twin_cosim.optimize.early_stop.EvaluationTask`): when the
candidate's fitness is certain to exceed it, the runs stop early and the result has status
``stopped`` with a lower bound as fitness (see :mod:`twin_cosim.optimize.early_stop`, which also
orders the cases). A candidate below the cutoff gets the same fitness in any case order, one
above it the same lower bound (or, when a run fails before one stops it, the failure's score,
also above the cutoff).

Built in a worker from :class:`~twin_cosim.optimize.axis_problem.ObjectiveSpec`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin_cosim.controller import ControllerSettings
from twin_cosim.cosim import RunAborted, run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.axis_problem import ObjectiveSpec
from twin_cosim.optimize.config import OptimizeConfig, load_config
from twin_cosim.optimize.early_stop import (
    CaseOrder,
    EvaluationTask,
    OwnEvaluations,
    allowance,
    least_fitness,
    lower_bound_above,
    window_spans_run,
)
from twin_cosim.optimize.evaluators import evaluation_result
from twin_cosim.oscillation import record_findings
from twin_cosim.plant import Plant, PlantError
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario


@dataclass(frozen=True)
class _Case:
    """One run of a candidate: a scenario, its metrics window (start, end s; None: to the end), a
    plant sample (FMU parameter overrides), its IAU limit (A.s), its E_pk scale and its
    speed-loop steps."""

    label: str
    scenario: Scenario
    window: tuple[float, float | None]
    overrides: dict[str, float]
    iau_limit: float | None
    scale: float
    steps: int


class Objective:
    """Scores candidates on one plant instance (extracted and instantiated once, reset per run)."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.spec = spec
        self.scenario: Scenario = spec.scenarios[0]
        self.config: OptimizeConfig = load_config(self.scenario)
        fmu = self.scenario.plant_fmu(spec.fmu)
        self.plant = Plant(fmu)
        start = self.plant.start_values()
        samples = spec.samples or ({},)
        count = len(spec.scenarios) * len(samples)
        limits = spec.iau_limits or (spec.iau_limit,) * count
        scales = spec.scales or (1.0,) * count
        if len(limits) != count or len(scales) != count:
            raise ValueError(
                f"objective of {count} cases ({len(spec.scenarios)} scenarios x "
                f"{len(samples)} samples): got {len(limits)} IAU limits and {len(scales)} scales"
            )
        self.cases: list[_Case] = []
        for scenario in spec.scenarios:
            window = load_config(scenario).window
            nominal = {**start, **scenario.plant_parameters}
            ratio = scenario.settings.speed_steps_per_position_step
            for k, factors in enumerate(samples):
                overrides = {name: nominal[name] * f for name, f in factors.items()}
                label = scenario.name + (f"/sample{k}" if len(samples) > 1 else "")
                steps = len(scenario.reference.position) * ratio
                i = len(self.cases)
                self.cases.append(
                    _Case(label, scenario, window, overrides, limits[i], scales[i], steps)
                )
        self._order = CaseOrder(count)
        self._own = OwnEvaluations()
        self.exact_early_stop = all(
            window_spans_run(c.window, c.scenario.reference.duration) for c in self.cases
        )

    def reference_of(self, index: int) -> dict[str, Any]:
        """Metrics of case ``index`` run with its scenario's own parameters (Fine-Tune by
        default).

        Returns
        -------
        dict
            The case's ``case`` label and the metrics of
            :func:`twin_cosim.metrics.compute_metrics` over the case's objective window
            (``E_pk_um`` um, ``ITAE`` um.s^2, ``IAU`` A.s, ...).
        """
        case = self.cases[index]
        metrics = compute_metrics(self.record(None, index), case.window)
        return {"case": case.label, **metrics.as_dict()}

    def record(self, x: np.ndarray | None, index: int = 0) -> RunRecord:
        """The record of case ``index`` run with candidate ``x`` (physical units; None: the
        scenario's own set), for figures.

        Raises
        ------
        ValueError
            When the controller refuses the candidate's values.
        """
        case = self.cases[index]
        if x is None:
            return run_scenario(self.plant, case.scenario, plant_overrides=case.overrides)
        tuned, settings = self.config.candidate(x, case.scenario.settings)
        scenario = _with_settings(case.scenario, settings)
        return run_scenario(self.plant, scenario, tuned, plant_overrides=case.overrides)

    def __call__(self, task: np.ndarray | EvaluationTask) -> dict[str, Any]:
        """Evaluate one candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H, filter dimensions...]
        (physical units), or a task (its cutoff lowered by this worker's own complete
        evaluations of its generation, :class:`~twin_cosim.optimize.early_stop.OwnEvaluations`).

        Returns
        -------
        dict
            ``fitness`` (um), ``status`` (ok, violation, unstable, failed, stopped), ``reason``,
            ``metrics`` (None when the run did not complete; with several runs the aggregate
            and ``runs``) and ``steps`` (speed-loop steps simulated).
        """
        return self._own.evaluate(task, self.evaluate)

    def evaluate(self, x: np.ndarray, cutoff: float) -> dict[str, Any]:
        """The result of :meth:`__call__` for candidate ``x`` with cutoff ``cutoff`` (um)."""
        if not self.exact_early_stop:
            cutoff = math.inf
        failure = 2.0 * self.config.penalty_um
        try:
            candidates = [self.config.candidate(x, case.scenario.settings) for case in self.cases]
        except ValueError as exc:
            return evaluation_result(failure, "failed", str(exc), None, 0)
        n = len(self.cases)
        aggregate = self.spec.aggregate
        scores: dict[int, float] = {}
        runs: dict[int, dict[str, Any]] = {}
        steps = 0
        for i in self._order:
            case = self.cases[i]
            allowed = allowance(cutoff, scores.values(), n, aggregate)
            abort_um = min(self.config.abort_error_um, max(allowed, 0.0) / case.scale)
            tuned, settings = candidates[i]
            try:
                record = run_scenario(
                    self.plant,
                    _with_settings(case.scenario, settings),
                    tuned,
                    plant_overrides=case.overrides,
                    abort_error=abort_um * 1e-6,
                )
            except RunAborted as exc:
                steps += _steps_until(case, exc.time_s)
                if abort_um < self.config.abort_error_um:
                    self._order.first(i)
                    reason = f"{case.label}: {exc}; fitness above the cutoff {cutoff:.6g} um"
                    return evaluation_result(
                        lower_bound_above(cutoff), "stopped", reason, None, steps
                    )
                return evaluation_result(failure, "unstable", f"{case.label}: {exc}", None, steps)
            except PlantError as exc:
                return evaluation_result(failure, "failed", f"{case.label}: {exc}", None, steps)
            steps += case.steps
            oscillating = record_findings(record, case.scenario.settings.current_limit)
            if oscillating:
                return evaluation_result(
                    failure, "unstable", f"{case.label}: {oscillating[0]}", None, steps
                )
            metrics = compute_metrics(record, case.window).as_dict()
            scores[i], status, reason = self._score(metrics, case)
            runs[i] = {"case": case.label, "status": status, "reason": reason, **metrics}
            bound = least_fitness(scores.values(), n, aggregate)
            if bound > cutoff and len(scores) < n:
                self._order.first(i)
                reason = f"{case.label}: fitness at least {bound:.6g} um, above the cutoff"
                return evaluation_result(lower_bound_above(cutoff), "stopped", reason, None, steps)
        if n == 1:
            run = runs[0]
            metrics = {k: v for k, v in run.items() if k not in ("case", "status", "reason")}
            return evaluation_result(scores[0], run["status"], run["reason"], metrics, steps)
        ordered = [runs[i] for i in range(n)]
        values = [scores[i] for i in range(n)]
        worst = int(np.argmax(values))
        self._order.first(worst)
        combine = max if aggregate == "worst" else (lambda v: sum(v) / len(v))
        metrics = {
            name: float(combine([r[name] for r in ordered])) for name in ("E_pk_um", "ITAE", "IAU")
        }
        metrics["runs"] = ordered
        status = "ok" if all(r["status"] == "ok" for r in ordered) else "violation"
        reason = "; ".join(r["reason"] for r in ordered if r["reason"])
        return evaluation_result(
            float(combine(values)),
            status,
            reason or f"worst run: {ordered[worst]['case']}",
            metrics,
            steps,
        )

    def _score(self, metrics: dict[str, float], case: _Case) -> tuple[float, str, str]:
        """Fitness (um), status and reason of one completed run of ``case``."""
        score = case.scale * metrics["E_pk_um"]
        if self.spec.settling_weight and metrics["settling_ms"] is not None:
            score += case.scale * self.spec.settling_weight * metrics["settling_ms"]
        limit = case.iau_limit
        if limit is not None and metrics["IAU"] > limit:
            reason = f"IAU {metrics['IAU']:.4g} A.s above the cap {limit:.4g} A.s"
            return self.config.penalty_um + score, "violation", reason
        return score, "ok", ""

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def _with_settings(scenario: Scenario, settings: ControllerSettings) -> Scenario:
    """The scenario with a candidate's settings (itself when they are its own)."""
    return (
        scenario
        if settings is scenario.settings
        else dataclasses.replace(scenario, settings=settings)
    )


def _steps_until(case: _Case, time_s: float) -> int:
    """Speed-loop steps simulated by a run stopped at position-loop time ``time_s``."""
    if not math.isfinite(time_s):
        return case.steps
    ratio = case.steps // len(case.scenario.reference.position)
    return int(round(time_s / case.scenario.reference.period)) * ratio
