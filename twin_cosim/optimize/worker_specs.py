"""What a campaign sends its workers: the recipes of the objective and of the reference runs,
and the tasks.

Light to import (no numba, pandas or fmpy): the parent of a process pool builds these values and
never runs the plant; the workers build :class:`~twin_cosim.optimize.objective.Objective` from
them (:meth:`ObjectiveSpec.build`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from twin_cosim.scenario import Scenario
    from twin_cosim.workers import Worker

AGGREGATES = ("worst", "mean")


# The module of the workers these recipes build, imported by name in the process that runs them:
# the recipes stay light (the parent never loads the co-simulation), and the workers' module
# depends on the recipes, not the other way round.
RUN_MODULE = "twin_cosim.optimize.objective"


@dataclass(frozen=True)
class EvaluationTask:
    """A candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] (then any filter dimensions), the
    cutoff (um) of its fitness, and the generation it belongs to.

    Attributes
    ----------
    x : numpy.ndarray
        The candidate, physical units.
    cutoff_um : float
        The cutoff known when the task was sent, um (inf: none).
    generation : str
        The generation's key, unique across the campaigns a pool runs ("": none).
    elite : int
        The generation's elite count: that many of its complete values make a cutoff (0: no
        cutoff). A worker lowers the cutoff by its own complete evaluations of the generation
        (:class:`~twin_cosim.optimize.early_stop.OwnEvaluations`).
    """

    x: np.ndarray
    cutoff_um: float = math.inf
    generation: str = ""
    elite: int = 0


@dataclass(frozen=True)
class ObjectiveSpec:
    """Everything a worker needs to build the objective (picklable: resolved values only).

    Attributes
    ----------
    scenarios : tuple of Scenario
        The objective's scenarios, resolved once by the parent (any plant parameter file
        applied); the first one's ``optimize`` section configures the objective, the others
        make it robust.
    fmu : str or None
        Plant FMU; the first scenario's (or the project's drive2mass) when None.
    iau_limit : float or None
        Largest allowed IAU, A.s, of every case when ``iau_limits`` is empty; None: no cap.
    iau_limits : tuple
        IAU limit of each case, A.s (None: no cap), in case order: scenario by scenario,
        plant sample by sample within each.
    samples : tuple of dict
        Plant samples: relative factors by FMU parameter name; none: the nominal plant only.
    aggregate : str
        ``worst`` or ``mean`` over the runs.
    scales : tuple of float
        Factor on each case's E_pk (case order); empty: 1 for every case.
    """

    scenarios: tuple[Scenario, ...]
    fmu: str | None
    iau_limit: float | None
    iau_limits: tuple[float | None, ...] = ()
    samples: tuple[dict[str, float], ...] = ()
    aggregate: str = "worst"
    scales: tuple[float, ...] = ()

    def build(self) -> Worker:
        """The objective (:class:`~twin_cosim.optimize.objective.Objective`, a worker of
        :mod:`twin_cosim.workers`), in the process that runs it."""
        return import_module(RUN_MODULE).Objective(self)


@dataclass(frozen=True)
class ReferenceSpec:
    """The recipe of a worker that runs the reference set of the objective's cases.

    Its tasks are case indices (the objective's case order); each answers that case's metrics
    (:meth:`~twin_cosim.optimize.objective.Objective.reference_of`).
    """

    objective: ObjectiveSpec

    def build(self) -> Worker:
        """The worker (:class:`~twin_cosim.optimize.objective.ReferenceRuns`), in the process that
        runs it."""
        return import_module(RUN_MODULE).ReferenceRuns(self.objective)
