"""The objective of eq. (12): one closed-loop run per candidate K, scored by E_pk.

A candidate's fitness (um) is

- E_pk over the objective window when the run is valid;
- penalty + E_pk when it violates the control-effort cap (IAU above the limit);
- 2 x penalty when it fails: parameters the controller refuses, a run stopped because the error
  left the allowed band (unstable loop), or an FMU error. The reason is kept with the result.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.controller import TunedParameters
from twin_cosim.cosim import RunAborted, run_scenario
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.config import OptimizeConfig, load_config
from twin_cosim.plant import Plant, PlantError
from twin_cosim.scenario import Scenario, load_scenario


@dataclass(frozen=True)
class ObjectiveSpec:
    """Everything a worker needs to build the objective (picklable: paths and numbers only).

    Attributes
    ----------
    scenario : str
        Scenario file.
    fmu : str or None
        Plant FMU; the scenario's (or the project's drive2mass) when None.
    iau_limit : float or None
        Largest allowed IAU, A.s; None: no cap.
    """

    scenario: str
    fmu: str | None
    iau_limit: float | None

    def build(self) -> Objective:
        """The objective (a worker of :mod:`twin_cosim.workers`)."""
        return Objective(self)


class Objective:
    """Scores candidates on one plant instance (extracted and instantiated once, reset per run)."""

    def __init__(self, spec: ObjectiveSpec) -> None:
        self.spec = spec
        self.scenario: Scenario = load_scenario(spec.scenario)
        self.config: OptimizeConfig = load_config(self.scenario)
        fmu = Path(spec.fmu) if spec.fmu else self.scenario.fmu
        self.plant = Plant(fmu)

    def __call__(self, x: np.ndarray) -> dict[str, Any]:
        """Evaluate one candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] (physical units).

        Returns
        -------
        dict
            ``fitness`` (um), ``status`` (ok, violation, unstable, failed), ``reason`` and
            ``metrics`` (None when the run did not complete).
        """
        failure = 2.0 * self.config.penalty_um
        try:
            tuned = TunedParameters.from_array(x)
        except ValueError as exc:
            return {"fitness": failure, "status": "failed", "reason": str(exc), "metrics": None}
        try:
            record = run_scenario(
                self.plant, self.scenario, tuned, abort_error=self.config.abort_error_um * 1e-6
            )
        except RunAborted as exc:
            return {"fitness": failure, "status": "unstable", "reason": str(exc), "metrics": None}
        except PlantError as exc:
            return {"fitness": failure, "status": "failed", "reason": str(exc), "metrics": None}
        metrics = compute_metrics(record, self.config.window).as_dict()
        limit = self.spec.iau_limit
        if limit is not None and metrics["IAU"] > limit:
            return {
                "fitness": self.config.penalty_um + metrics["E_pk_um"],
                "status": "violation",
                "reason": f"IAU {metrics['IAU']:.4g} A.s above the cap {limit:.4g} A.s",
                "metrics": metrics,
            }
        return {"fitness": metrics["E_pk_um"], "status": "ok", "reason": "", "metrics": metrics}

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()
