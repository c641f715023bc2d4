"""A single axis' tuning problem: the six of eq. (7) (and any filter dimensions) on scenarios.

What a campaign is asked (:class:`CampaignSpec`), and the problem the driver runs
(:class:`AxisProblem`, :mod:`twin_cosim.optimize.driver`): its scenarios, resolved once in the
parent with the plant parameter file (and the start set, if given), on each plant sample. A
case is a scenario on a plant sample (relative factors on the uncertain plant parameters, the
first sample the nominal plant); the workers run each case's reference (the scenario's own set)
and then the candidates, from the recipe of :class:`ObjectiveSpec` (resolved values only:
nothing is loaded again there).

Light to import (no numba, pandas or fmpy): the parent of a process pool builds these values and
never runs the plant; the workers build :class:`~twin_cosim.optimize.objective.Objective` from
them.

``campaign.json`` holds what was asked (scenario, method, seed, budget, settings, bounds, the
Fine-Tune reference metrics and the IAU limit; per case its reference run, IAU limit and E_pk
scale; the plant parameters, the scenarios and the plant samples, which a resume checks against
the files as they are now) and the content fingerprints of the scenario, the plant FMU and the
settings.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin_cosim import current_filters
from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.controller_set import ControllerSet
from twin_cosim.optimize.algorithms import method_settings
from twin_cosim.optimize.config import (
    OptimizeConfig,
    UncertaintySet,
    check_uncertainty,
    load_config,
    relative_ranges,
    uncertain_parameters,
)
from twin_cosim.optimize.early_stop import window_spans_run
from twin_cosim.optimize.store import (
    CampaignError,
    check_same_inputs,
    digest,
    fmu_fingerprint,
    load_spec,
    settings_fingerprint,
)
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import (
    Scenario,
    load_controller_set,
    resolve_scenario,
    with_controller_set,
)
from twin_cosim.scenario.plant_parameters import read_plant_parameters
from twin_cosim.workers import prepare_campaign_worker

if TYPE_CHECKING:
    import numpy as np

    from twin_cosim.workers import Worker

AGGREGATES = ("worst", "mean")
# Plant samples per scenario by default when the plant parameter file has intervals: the
# calibrated plant and three draws within them (robust tuning by default in the transfer path).
INTERVAL_SAMPLES = 4
# What a single axis' campaign.json holds besides its spec (and the type of each)
RECORD_KEYS: Mapping[str, type] = {"iau_limit": object, "reference": dict}
# The module of the workers the recipes build, imported by name in the process that runs them:
# the recipes stay light (the parent never loads the co-simulation), and the workers' module
# depends on the recipes, not the other way round.
RUN_MODULE = "twin_cosim.optimize.objective"


@dataclass(frozen=True)
class CampaignSpec:
    """What a single axis' campaign optimizes and how (stored in ``campaign.json``).

    Attributes
    ----------
    scenario : str
        Scenario file (its ``optimize`` section configures the objective).
    method : str
        A name of :data:`twin_cosim.optimize.algorithms.METHOD_NAMES`.
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
        Relative tolerance of the uncertain plant parameters (those without an interval in
        the plant parameter file).
    samples : int or None
        Plant samples per scenario (1: the nominal plant only); None: the default,
        :data:`INTERVAL_SAMPLES` when the plant parameter file has intervals (what its
        diagnosis leaves uncertain: the transfer path tunes robustly over them), else 1.
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
    settling_weight : float
        um of fitness per ms of settling time (:data:`twin_cosim.metrics.Metrics.settling_ms`)
        added to each run's E_pk; 0: the paper's objective, E_pk alone.
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
    samples: int | None = None
    aggregate: str = "worst"
    relative: bool = False
    early_stop: bool = True
    start: str | None = None
    settling_weight: float = 0.0


def load_campaign_spec(out_dir: Path) -> CampaignSpec:
    """The spec of the single axis' campaign stored in ``out_dir`` (for ``--resume``)."""
    return load_spec(out_dir, CampaignSpec, RECORD_KEYS)


def campaign_scenarios(spec: CampaignSpec) -> tuple[Scenario, ...]:
    """The campaign's scenarios (``scenario`` first), resolved with its plant parameter file;
    with a start set (``spec.start``), each runs that set as its own."""
    scenarios = tuple(
        resolve_scenario(path, spec.plant_parameters, spec.fmu)
        for path in (spec.scenario, *spec.scenarios)
    )
    if spec.start is None:
        return scenarios
    start = load_controller_set(spec.start)
    return tuple(with_controller_set(scenario, start) for scenario in scenarios)


@dataclass(frozen=True)
class AxisProblem:
    """A single axis' campaign as the driver runs it (:class:`~twin_cosim.optimize.driver.Problem`).

    Attributes
    ----------
    spec : CampaignSpec
        What was asked (``campaign.json``'s ``spec``): scenarios, method, seed, robust options.
    scenarios : tuple of Scenario
        Its scenarios, resolved (:func:`campaign_scenarios`).
    config : OptimizeConfig
        The first scenario's ``optimize`` section.
    robust : dict
        The plant parameters, scenarios and plant samples as the files are now
        (:func:`robust_settings`).
    """

    spec: CampaignSpec
    scenarios: tuple[Scenario, ...]
    config: OptimizeConfig
    robust: dict[str, Any]

    record_keys = RECORD_KEYS
    prepare_worker = staticmethod(prepare_campaign_worker)

    @classmethod
    def resolve(cls, spec: CampaignSpec) -> AxisProblem:
        """The problem of ``spec``: its scenarios resolved now (:func:`campaign_scenarios`), its
        ``optimize`` section checked and its plant samples drawn.

        Raises
        ------
        CampaignError, ValueError, ScenarioError
            On a bad objective, tolerance or sample count, or a file that cannot be read.
        """
        scenarios = campaign_scenarios(spec)
        config = load_config(scenarios[0])
        return cls(spec, scenarios, config, robust_settings(spec, scenarios))

    @property
    def case_count(self) -> int:
        """The runs of every candidate: each scenario on each plant sample."""
        return len(self.scenarios) * (len(self.robust["samples"]) or 1)

    def start(self) -> np.ndarray:
        """The first scenario's own set (Fine-Tune by default, or the start set): its six, then
        its filter values."""
        scenario = self.scenarios[0]
        return self.config.start(scenario.tuned, scenario.settings)

    def method_settings(self) -> dict[str, Any]:
        """The method's settings: the scenario's, the spec's on top, and the spec's budget."""
        spec = self.spec
        configured = self.config.methods.get(spec.method, {})
        return method_settings(spec.method, spec.start, configured, spec.settings, spec.budget)

    def fingerprints(self, settings: dict[str, Any]) -> dict[str, str]:
        """Content fingerprints of the campaign's first scenario, plant FMU and settings."""
        spec = self.spec
        fmu = self.scenarios[0].plant_fmu(spec.fmu)
        chosen = {"method": spec.method, "seed": spec.seed, "settings": settings}
        if spec.start is not None:  # the start set's content, not its path
            chosen["start"] = load_controller_set(spec.start).as_dict()
        return {
            "scenario": scenario_fingerprint(self.scenarios[0]),
            "plant_fmu": fmu_fingerprint(fmu),
            "settings": settings_fingerprint({**chosen, "config": self.config.as_dict()}),
        }

    def check_stored(self, out_dir: Path, record: dict[str, Any], found: dict[str, str]) -> None:
        """Refuse a resume whose scenario, plant FMU, settings, plant parameters or robust
        settings differ from the stored campaign's (paths aside: a moved file resumes)."""
        spec = self.spec
        names = {
            "scenario": f"scenario {spec.scenario}",
            "plant_fmu": f"plant FMU {spec.fmu or 'of the scenario'}",
            "settings": "optimizer settings",
        }
        check_same_inputs(out_dir, record, found, names)
        stored = record.get("robust") or {}
        robust = self.robust
        changed = sorted(k for k in robust if k != "scenarios" and stored.get(k) != robust[k])
        if changed:
            raise CampaignError(
                f"{out_dir}: the campaign's {changed} changed since it started (plant parameter "
                "file or robust settings); start a new campaign"
            )

    def objective(self, record: dict[str, Any] | None) -> ObjectiveSpec:
        """What the workers build their objective from: the resolved scenarios and the cases.

        ``record`` is the campaign's record (``campaign.json``): its IAU limit (A.s), cases and
        plant samples; None: the cases without limits nor scales (their reference runs).
        """
        spec = self.spec
        if record is None:
            samples = tuple(self.robust["samples"])
            return ObjectiveSpec(self.scenarios, spec.fmu, None, samples=samples)
        cases = record.get("cases") or []
        return ObjectiveSpec(
            self.scenarios,
            spec.fmu,
            record["iau_limit"],
            tuple(c["iau_limit"] for c in cases),
            tuple((record.get("robust") or {}).get("samples") or ()),
            spec.aggregate,
            tuple(c["scale"] for c in cases),
            spec.settling_weight,
        )

    def new_record(self, references: list[dict[str, Any]], found: dict[str, str]) -> dict:
        """The record of a new campaign from each case's reference run (the scenario's own set,
        Fine-Tune by default, on the case's plant sample) and the fingerprints.

        A case's IAU limit (A.s) is the cap times its reference's IAU, so that a plant sample
        needing more current does not penalise every candidate; its scale is 1, or for a
        relative objective the first case's reference E_pk over its own.
        """
        spec, config = self.spec, self.config
        first = references[0]["E_pk_um"]
        cases = []
        for reference in references:
            if spec.relative and not reference["E_pk_um"] > 0.0:
                raise CampaignError(
                    f"{reference['case']}: the reference set's E_pk is {reference['E_pk_um']} um; "
                    "a relative objective needs it above 0"
                )
            cases.append(
                {
                    "case": reference.pop("case"),
                    "reference": reference,
                    "iau_limit": None
                    if config.iau_cap is None
                    else config.iau_cap * reference["IAU"],
                    "scale": first / reference["E_pk_um"] if spec.relative else 1.0,
                }
            )
        return {
            "spec": asdict(spec),
            "config": config.as_dict(),
            "reference": {
                "params": self.scenarios[0].tuned.as_dict(),
                "metrics": cases[0]["reference"],
            },
            "iau_limit": cases[0]["iau_limit"],
            "fingerprints": found,
            "cases": cases,
            "robust": self.robust,
        }

    def cutoff_is_exact(self) -> bool:
        """Whether every scenario's objective window spans its run (an error outside it would
        stop a run without counting in E_pk)."""
        return all(
            window_spans_run(load_config(s).window, s.reference.duration) for s in self.scenarios
        )

    def best(self, x: np.ndarray, record: dict[str, Any]) -> dict[str, Any]:
        """The best candidate's parameters by name, the reference metrics of the first case, and
        the filters it sets (``settings``) when the campaign tuned filter dimensions."""
        settings: dict[str, Any] = {}
        if self.config.filters:
            _, chosen = self.config.candidate(x, self.scenarios[0].settings)
            settings = {"filters": [current_filters.as_dict(f) for f in chosen.filters]}
        return {
            "best_params": self.config.parameters(x),
            "reference": record["reference"]["metrics"],
            "details": {"settings": settings},
        }


def robust_settings(spec: CampaignSpec, scenarios: tuple[Scenario, ...]) -> dict[str, Any]:
    """The plant parameters, scenarios and plant samples of a campaign as its files are now.

    Parameters
    ----------
    spec
        The campaign.
    scenarios
        Its scenarios as :func:`campaign_scenarios` resolves them.

    Returns
    -------
    dict
        ``plant_parameters`` (the parameter file's values, SI units), ``scenarios`` (the
        files), ``scenarios_sha256`` (their contents), ``scenario_plant_parameters`` (each
        scenario's, any parameter file folded in), ``uncertain_parameters``, ``intervals``
        (with a plant parameter file that has intervals: each one's range of relative factors)
        and ``samples`` (relative factors of each plant sample; none for the nominal plant
        only). The uncertain parameters are those of the file's intervals and, with a tolerance
        above 0, the model's calibrated ones and the file's other non-zero real values.
    """
    if spec.aggregate not in AGGREGATES:
        raise CampaignError(f"objective {spec.aggregate!r}: expected one of {AGGREGATES}")
    if not spec.settling_weight >= 0.0:
        raise CampaignError(
            f"objective settling={spec.settling_weight}: expected a weight >= 0 um per ms"
        )
    model = scenarios[0].model_name(spec.fmu)
    plant = read_plant_parameters(spec.plant_parameters, model) if spec.plant_parameters else None
    calibrated = plant.parameters if plant else {}
    nominal = {**plant_model(model).start_values(), **scenarios[0].plant_parameters}
    ranges = relative_ranges(plant.intervals, nominal) if plant else {}
    samples = spec.samples if spec.samples is not None else INTERVAL_SAMPLES if ranges else 1
    check_uncertainty(spec.tolerance, samples)
    if samples > 1 and spec.tolerance == 0.0 and not ranges:
        raise ValueError(
            "--samples above 1 needs a --tolerance above 0 (e.g. 0.03) or a --plant-parameters "
            "file with intervals (twin diagnose writes them)"
        )
    names = uncertain_parameters(model, calibrated) if spec.tolerance > 0.0 else ()
    uncertainty = UncertaintySet(
        spec.tolerance, samples, spec.seed, tuple(dict.fromkeys([*names, *ranges])), ranges
    )
    robust = {
        "plant_parameters": calibrated,
        "scenarios": [spec.scenario, *spec.scenarios],
        "scenarios_sha256": [hashlib.sha256(s.source.read_bytes()).hexdigest() for s in scenarios],
        "scenario_plant_parameters": [s.plant_parameters for s in scenarios],
        "uncertain_parameters": list(uncertainty.parameters),
        "samples": uncertainty.factors() if samples > 1 else [],
    }
    if ranges:
        robust["intervals"] = {name: list(r) for name, r in ranges.items()}
    return robust


def scenario_fingerprint(scenario: Scenario) -> str:
    """The scenario file's bytes plus the reference and disturbance they resolve to.

    The resolved arrays cover what the file only names (a reference CSV, a measured run).
    """
    disturbance = b"" if scenario.disturbance is None else scenario.disturbance.tobytes()
    return digest(
        Path(scenario.source).read_bytes(), scenario.reference.position.tobytes(), disturbance
    )


def controller_set_of(result: Mapping[str, Any]) -> ControllerSet:
    """The controller set of a campaign's result (``result.json``): the six, any filters."""
    six = TunedParameters(**{name: result["best_params"][name] for name in TUNED_NAMES})
    filters = (result.get("settings") or {}).get("filters")
    if filters is None:
        return ControllerSet(six)
    return ControllerSet(six, {"filters": tuple(current_filters.from_dict(f) for f in filters)})


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
    settling_weight : float
        um of fitness per ms of a run's settling time; 0: E_pk alone.
    """

    scenarios: tuple[Scenario, ...]
    fmu: str | None
    iau_limit: float | None
    iau_limits: tuple[float | None, ...] = ()
    samples: tuple[dict[str, float], ...] = ()
    aggregate: str = "worst"
    scales: tuple[float, ...] = ()
    settling_weight: float = 0.0

    def build(self) -> Worker:
        """The objective (:class:`~twin_cosim.optimize.objective.Objective`, a worker of
        :mod:`twin_cosim.workers`), in the process that runs it."""
        return import_module(RUN_MODULE).Objective(self)
