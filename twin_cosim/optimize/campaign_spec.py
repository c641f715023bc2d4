"""What a campaign is asked (:class:`CampaignSpec`) and what it found (:class:`CampaignResult`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from twin_cosim import current_filters
from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.controller_set import ControllerSet


class CampaignError(ValueError):
    """A campaign cannot start or resume; the message says why."""


@dataclass(frozen=True)
class CampaignSpec:
    """What a campaign optimizes and how (stored in ``campaign.json``).

    Attributes
    ----------
    scenario : str
        Scenario file (its ``optimize`` section configures the objective).
    method : str
        A name of :data:`twin_cosim.optimize.methods.METHODS`.
    seed : int
        Seed of the optimizer.
    budget : int or None
        Maximum evaluations; the method's default when None.
    fmu : str or None
        Plant FMU; the scenario's when None.
    settings : dict
        Method settings (overrides of the scenario's ``optimize.methods.<method>``).
    plant_parameters : str or None
        Plant parameter file (``plant.yaml``) applied to every scenario.
    scenarios : list of str
        Further scenarios of a robust objective.
    tolerance : float
        Relative tolerance of the uncertain plant parameters.
    samples : int
        Plant samples per scenario (1: the nominal plant only).
    aggregate : str
        ``worst`` or ``mean`` over scenarios x samples.
    relative : bool
        Score each run's E_pk relative to the reference set's E_pk on the same scenario and
        plant sample, in units of the first scenario's nominal reference E_pk (um).
    early_stop : bool
        Stop runs early where that is exact.
    start : str or None
        A controller-set file (e.g. ``twin autotune``'s) the campaign starts from: its set
        becomes every scenario's own (the start point and the reference of the IAU cap).
    """

    scenario: str
    method: str
    seed: int = 0
    budget: int | None = None
    fmu: str | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    plant_parameters: str | None = None
    scenarios: list[str] = field(default_factory=list)
    tolerance: float = 0.0
    samples: int = 1
    aggregate: str = "worst"
    relative: bool = False
    early_stop: bool = True
    start: str | None = None


@dataclass
class CampaignResult:
    """Outcome of a campaign (also written to ``result.json``).

    Attributes
    ----------
    method : str
        The optimizer's name.
    best_params : dict
        The best candidate [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] by name (physical units),
        then its filter dimensions (``filter<k>.<parameter>``), if any were tuned.
    fitness : float
        Its fitness, um (E_pk, plus any penalty).
    status : str
        Its status (ok, violation, ...; see :mod:`twin_cosim.optimize.objective`).
    metrics : dict or None
        Its metrics (E_pk_um um, ITAE um.s^2, IAU A.s, ...; per case as ``runs`` when robust).
    evaluations : int
        Candidates the optimizer was told about.
    evaluations_reused : int
        Of those, answered from a log written before this run (a resume).
    generations : int
        Generations told.
    stop_reason : str
        Why the optimizer stopped.
    wall_s : float
        Wall time of the ask/tell loop, s.
    reference : dict
        Metrics of the scenario's own parameter set (Fine-Tune by default) on the first case.
    out_dir : str
        The campaign folder.
    settings : dict
        The controller settings the best candidate changed: ``filters`` (as a scenario writes
        them) when filter dimensions were tuned, else empty.
    """

    method: str
    best_params: dict[str, float]
    fitness: float
    status: str
    metrics: dict[str, float] | None
    evaluations: int
    evaluations_reused: int
    generations: int
    stop_reason: str
    wall_s: float
    reference: dict[str, float]
    out_dir: str
    settings: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def controller_set_of(result: Mapping[str, Any]) -> ControllerSet:
    """The controller set of a campaign's result (``result.json``): the six, any filters."""
    six = TunedParameters(**{name: result["best_params"][name] for name in TUNED_NAMES})
    filters = (result.get("settings") or {}).get("filters")
    if filters is None:
        return ControllerSet(six)
    return ControllerSet(six, {"filters": tuple(current_filters.from_dict(f) for f in filters)})
