"""The cases of a campaign: its scenarios, resolved once, on each plant sample.

A case is a scenario on a plant sample (relative factors on the uncertain plant parameters, the
first sample the nominal plant). The parent resolves the scenarios once
(:func:`campaign_scenarios`), has its workers run each case's reference
(:func:`case_references`) and sends them the resolved values (:func:`objective_spec`); nothing
is loaded again there.
"""

from __future__ import annotations

import hashlib
from typing import TYPE_CHECKING, Any

from twin_cosim.optimize.campaign_spec import CampaignError, CampaignSpec
from twin_cosim.optimize.config import (
    OptimizeConfig,
    UncertaintySet,
    check_uncertainty,
    load_config,
    uncertain_parameters,
)
from twin_cosim.optimize.early_stop import EXACT_METHODS, window_spans_run
from twin_cosim.optimize.worker_specs import AGGREGATES, ObjectiveSpec, ReferenceSpec
from twin_cosim.scenario import Scenario, resolve_scenario
from twin_cosim.scenario.plant_file import read_plant_parameters

if TYPE_CHECKING:
    from twin_cosim.workers import ProcessPool, SerialPool


def campaign_scenarios(spec: CampaignSpec) -> tuple[Scenario, ...]:
    """The campaign's scenarios (``scenario`` first), resolved with its plant parameter file."""
    return tuple(
        resolve_scenario(path, spec.plant_parameters, spec.fmu)
        for path in (spec.scenario, *spec.scenarios)
    )


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
        scenario's, any parameter file folded in), ``uncertain_parameters`` and ``samples``
        (relative factors of each plant sample; none for the nominal plant only).
    """
    if spec.aggregate not in AGGREGATES:
        raise CampaignError(f"objective {spec.aggregate!r}: expected one of {AGGREGATES}")
    check_uncertainty(spec.tolerance, spec.samples)
    if spec.samples > 1 and spec.tolerance == 0.0:
        raise ValueError("--samples above 1 needs a --tolerance above 0 (e.g. 0.03)")
    model = scenarios[0].model_name(spec.fmu)
    calibrated = (
        read_plant_parameters(spec.plant_parameters, model).parameters
        if spec.plant_parameters
        else {}
    )
    uncertainty = UncertaintySet(
        spec.tolerance, spec.samples, spec.seed, uncertain_parameters(model, calibrated)
    )
    return {
        "plant_parameters": calibrated,
        "scenarios": [spec.scenario, *spec.scenarios],
        "scenarios_sha256": [hashlib.sha256(s.source.read_bytes()).hexdigest() for s in scenarios],
        "scenario_plant_parameters": [s.plant_parameters for s in scenarios],
        "uncertain_parameters": list(uncertainty.parameters),
        "samples": uncertainty.factors() if spec.samples > 1 else [],
    }


def case_references(
    spec: CampaignSpec,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    samples: list[dict[str, float]],
    pool: SerialPool | ProcessPool,
) -> list[dict[str, Any]]:
    """Each case's reference run (on the pool's workers), IAU limit and E_pk scale.

    A case is a scenario on a plant sample. Its reference is the scenario's own parameter set
    (Fine-Tune by default) run on that plant sample; its IAU limit (A.s) is the cap times the
    reference's IAU, so that a plant sample needing more current does not penalise every
    candidate; its scale is 1, or for a relative objective the first case's reference E_pk over
    its own.
    """
    probe = ReferenceSpec(ObjectiveSpec(scenarios, spec.fmu, None, samples=tuple(samples)))
    count = len(scenarios) * (len(samples) or 1)  # the objective's cases
    found = dict(pool.imap(range(count), probe))
    references = [found[i] for i in range(count)]
    first = references[0]["E_pk_um"]
    cases = []
    for reference in references:
        if spec.relative and not reference["E_pk_um"] > 0.0:
            raise CampaignError(
                f"{reference['case']}: the reference set's E_pk is {reference['E_pk_um']} um; a "
                "relative objective needs it above 0"
            )
        cases.append(
            {
                "case": reference.pop("case"),
                "reference": reference,
                "iau_limit": None if config.iau_cap is None else config.iau_cap * reference["IAU"],
                "scale": first / reference["E_pk_um"] if spec.relative else 1.0,
            }
        )
    return cases


def objective_spec(
    spec: CampaignSpec, scenarios: tuple[Scenario, ...], header: dict[str, Any]
) -> ObjectiveSpec:
    """What the workers build their objective from: the resolved scenarios and the cases.

    ``header`` is the campaign's record (``campaign.json``): its IAU limit (A.s), cases and
    plant samples.
    """
    cases = header.get("cases") or []
    return ObjectiveSpec(
        scenarios,
        spec.fmu,
        header["iau_limit"],
        tuple(c["iau_limit"] for c in cases),
        tuple((header.get("robust") or {}).get("samples") or ()),
        spec.aggregate,
        tuple(c["scale"] for c in cases),
    )


def early_stop_exact(method: str, scenarios: tuple[Scenario, ...]) -> bool:
    """Whether the method and every scenario's objective window allow exact early stopping."""
    return method in EXACT_METHODS and all(
        window_spans_run(load_config(s).window, s.reference.duration) for s in scenarios
    )
