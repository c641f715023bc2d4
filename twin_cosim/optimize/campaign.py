"""Optimizer campaigns: ask/tell loop, evaluation log, checkpoints, resume, results.

A campaign folder holds

- ``campaign.json``: what was asked (scenario, method, seed, budget, settings, bounds, the
  Fine-Tune reference metrics and the IAU limit; per case, a scenario on a plant sample, its
  reference run, IAU limit and E_pk scale; for a calibrated or robust campaign also the plant
  parameters, the scenarios and the plant samples, which a resume checks against the files as
  they are now); ``--resume`` reads it back;
- ``evaluations.jsonl``: every completed evaluation, flushed at once (the checkpoint);
- ``progress.json``: rewritten after every generation (generation, evaluations, best so far);
- ``result.json``: the outcome (best parameters and metrics, evaluations, wall time).

``campaign.json`` also holds content fingerprints of the scenario, the plant FMU and the
settings: a resume whose inputs differ is refused, naming what changed. While a campaign runs,
``campaign.lock`` keeps a second writer out of the folder. Every argument is checked before
anything is written, so a mistake never blocks the folder.

The optimizer starts from the scenario's parameters (the Fine-Tune set by default) when they lie
inside the bounds. Resuming replays the optimizer from its seed, answering from the log every
batch already evaluated, so a resumed campaign ends exactly where an uninterrupted one would.

Early stopping (CE, on by default where exact, see :mod:`twin_cosim.optimize.early_stop`): a
generation's candidates go out in groups of as many as there are workers, each with the cutoff
known at that moment; a stopped candidate's lower bound is reused from the log only within its
own generation (elsewhere it is evaluated again).
"""

from __future__ import annotations

import hashlib
import json
import logging
import time
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.optimize.algorithms import make_optimizer
from twin_cosim.optimize.config import (
    OptimizeConfig,
    UncertaintySet,
    check_uncertainty,
    load_config,
    uncertain_parameters,
    within_bounds,
)
from twin_cosim.optimize.early_stop import EXACT_METHODS, elite_cutoff, window_spans_run
from twin_cosim.optimize.evaluation_log import EvaluationLog, candidate_key
from twin_cosim.optimize.evaluator_protocol import SchedulerError
from twin_cosim.optimize.evaluators import make_evaluator
from twin_cosim.optimize.fingerprints import (
    fmu_fingerprint,
    scenario_fingerprint,
    settings_fingerprint,
)
from twin_cosim.optimize.folder_lock import FolderLock, FolderLockedError
from twin_cosim.optimize.objective import AGGREGATES, EvaluationTask, Objective, ObjectiveSpec
from twin_cosim.plant import default_fmu
from twin_cosim.plant_parameters import fmu_model, read_plant_parameters
from twin_cosim.resolved_scenario import resolve_scenario
from twin_cosim.scenario import Scenario
from twin_cosim.workers import check_workers

LOG = logging.getLogger(__name__)


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


@dataclass
class CampaignResult:
    """Outcome of a campaign (also written to ``result.json``)."""

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

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return asdict(self)


def campaign_scenarios(spec: CampaignSpec) -> tuple[Scenario, ...]:
    """The campaign's scenarios (``scenario`` first), resolved with its plant parameter file."""
    return tuple(
        resolve_scenario(path, spec.plant_parameters, spec.fmu)
        for path in (spec.scenario, *spec.scenarios)
    )


def _robust_settings(spec: CampaignSpec, scenarios: tuple[Scenario, ...]) -> dict[str, Any]:
    """The plant parameters, scenarios and plant samples of a campaign as its files are now."""
    if spec.aggregate not in AGGREGATES:
        raise CampaignError(f"objective {spec.aggregate!r}: expected one of {AGGREGATES}")
    check_uncertainty(spec.tolerance, spec.samples)
    if spec.samples > 1 and spec.tolerance == 0.0:
        raise ValueError("--samples above 1 needs a --tolerance above 0 (e.g. 0.03)")
    model = fmu_model(spec.fmu or scenarios[0].fmu)
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
        "scenario_plant_parameters": [  # with any plant.parameters_file folded in
            s.plant_parameters for s in scenarios
        ],
        "uncertain_parameters": list(uncertainty.parameters),
        "samples": uncertainty.factors() if spec.samples > 1 else [],
    }


def case_references(
    spec: CampaignSpec,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    samples: list[dict[str, float]],
) -> list[dict[str, Any]]:
    """Each case's reference run, IAU limit and E_pk scale.

    A case is a scenario on a plant sample. Its reference is the scenario's own parameter set
    (Fine-Tune by default) run on that plant sample; its IAU limit (A.s) is the cap times the
    reference's IAU, so that a plant sample needing more current does not penalise every
    candidate; its scale is 1, or for a relative objective the first case's reference E_pk over
    its own.
    """
    probe = Objective(ObjectiveSpec(scenarios, spec.fmu, None, samples=tuple(samples)))
    try:
        references = probe.reference_metrics()
    finally:
        probe.close()
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


def _read_header(out_dir: Path) -> dict[str, Any]:
    path = Path(out_dir) / "campaign.json"
    if not path.is_file():
        raise CampaignError(f"{out_dir}: no campaign.json to resume from")
    try:
        header = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CampaignError(f"{path}: not a campaign record (JSON): {exc}") from exc
    if not isinstance(header, dict) or not isinstance(header.get("spec"), dict):
        raise CampaignError(f"{path}: not a campaign record: no 'spec' mapping")
    missing = sorted({"iau_limit", "reference"} - set(header))
    if missing or not isinstance(header["reference"], dict):
        raise CampaignError(
            f"{path}: not a campaign record: missing or bad {missing or 'reference'}"
        )
    return header


def fingerprints(
    spec: CampaignSpec, scenario: Scenario, config: OptimizeConfig, settings: dict[str, Any]
) -> dict[str, str]:
    """Content fingerprints of the campaign's scenario, plant FMU and settings."""
    fmu = Path(spec.fmu) if spec.fmu else (scenario.fmu or default_fmu())
    if not fmu.is_file() or not zipfile.is_zipfile(fmu):
        raise CampaignError(f"{fmu}: plant FMU not found or not an FMU (zip archive)")
    chosen = {"method": spec.method, "seed": spec.seed, "settings": settings}
    return {
        "scenario": scenario_fingerprint(scenario),
        "plant_fmu": fmu_fingerprint(fmu),
        "settings": settings_fingerprint({**chosen, "config": config.as_dict()}),
    }


def _check_resume(
    out_dir: Path, header: dict[str, Any], spec: CampaignSpec, found: dict[str, str]
) -> None:
    """Refuse a resume whose options or input contents differ from the stored campaign."""
    stored = {k: v for k, v in header["spec"].items() if k not in ("scenario", "fmu")}
    given = {k: v for k, v in asdict(spec).items() if k not in ("scenario", "fmu")}
    if stored != given:
        raise CampaignError(f"{out_dir}: holds a different campaign {stored}, not {given}")
    recorded = header.get("fingerprints")
    if not isinstance(recorded, dict):
        raise CampaignError(
            f"{out_dir}/campaign.json: holds no content fingerprints (an older campaign), so "
            "a resume cannot be checked against it; start a new campaign"
        )
    names = {
        "scenario": f"scenario {spec.scenario}",
        "plant_fmu": f"plant FMU {spec.fmu or 'of the scenario'}",
        "settings": "optimizer settings",
    }
    changed = [names[key] for key in names if recorded.get(key) != found[key]]
    if changed:
        raise CampaignError(
            f"{out_dir}: cannot resume: the {' and the '.join(changed)} changed since the "
            f"campaign started (content fingerprints differ); start a new campaign in another "
            "--out, or resume with the original inputs"
        )


def _prepare(
    spec: CampaignSpec,
    out_dir: Path,
    resume: bool,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    found: dict[str, str],
) -> dict[str, Any]:
    header_path = out_dir / "campaign.json"
    robust = _robust_settings(spec, scenarios)
    if resume:
        header = _read_header(out_dir)
        _check_resume(out_dir, header, spec, found)
        # the files' contents decide (scenarios_sha256), not their paths: a moved file resumes
        compared = [key for key in robust if key != "scenarios"]
        stored = {key: (header.get("robust") or {}).get(key) for key in compared}
        if any(stored[k] != robust[k] for k in compared):
            changed = sorted(k for k in compared if stored[k] != robust[k])
            raise CampaignError(
                f"{out_dir}: the campaign's {changed} changed since it started (plant parameter "
                "file or robust settings); start a new campaign"
            )
        return header
    if header_path.exists():
        raise CampaignError(
            f"{out_dir}: already holds a campaign; use --resume {out_dir} or another --out"
        )
    cases = case_references(spec, scenarios, config, robust["samples"])
    header = {
        "spec": asdict(spec),
        "config": config.as_dict(),
        "reference": {"params": scenarios[0].tuned.as_dict(), "metrics": cases[0]["reference"]},
        "iau_limit": cases[0]["iau_limit"],
        "fingerprints": found,
        "cases": cases,
        "robust": robust,
    }
    header_path.write_text(json.dumps(header, indent=2) + "\n")
    return header


def load_spec(out_dir: Path) -> CampaignSpec:
    """The spec of the campaign stored in ``out_dir`` (for ``--resume``)."""
    stored = _read_header(out_dir)["spec"]
    try:
        return CampaignSpec(**stored)
    except TypeError as exc:
        raise CampaignError(f"{Path(out_dir) / 'campaign.json'}: bad 'spec': {exc}") from exc


def _check_arguments(spec: CampaignSpec, out_dir: Path, workers: int | None, resume: bool) -> None:
    """Every argument, checked before anything is written."""
    for name, value, low in (("seed", spec.seed, 0), ("budget", spec.budget, 1)):
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or value < low
        ):
            raise CampaignError(f"{name}: expected a whole number >= {low}, got {value!r}")
    try:
        check_workers(workers)
    except ValueError as exc:
        raise CampaignError(str(exc)) from None
    if out_dir.exists() and not out_dir.is_dir():
        raise CampaignError(f"{out_dir}: exists and is not a folder (campaign folder expected)")
    if resume and not (out_dir / "campaign.json").is_file():
        raise CampaignError(f"{out_dir}: no campaign.json to resume from")


def run_campaign(
    spec: CampaignSpec,
    out_dir: Path,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    scheduler_timeout: float | None = None,
    scenarios: tuple[Scenario, ...] | None = None,
) -> CampaignResult:
    """Run (or resume) a campaign and write its folder.

    Parameters
    ----------
    spec
        What to optimize.
    out_dir
        Campaign folder.
    workers
        Local processes (1: serial in this process; None: all cores).
    scheduler
        Dask scheduler address; overrides ``workers``.
    resume
        Continue the campaign already in ``out_dir``.
    progress
        Show a progress bar on stderr.
    scheduler_timeout
        Seconds to wait for the Dask scheduler to answer, and again for a worker to join.
    scenarios
        The spec's scenarios as :func:`campaign_scenarios` resolves them, when the caller has
        them already; resolved here when None.

    Raises
    ------
    CampaignError
        On a bad argument (before anything is written), a folder in use by another process, or
        a resume whose options or inputs differ from the stored campaign.
    """
    out_dir = Path(out_dir)
    _check_arguments(spec, out_dir, workers, resume)
    if scenarios is None:
        scenarios = campaign_scenarios(spec)
    scenario = scenarios[0]
    config = load_config(scenario)
    settings = {**config.methods.get(spec.method, {}), **spec.settings}
    if spec.budget is not None:
        settings["budget"] = spec.budget
    x0 = (
        config.to_unit(scenario.tuned.as_array()) if within_bounds(config, scenario.tuned) else None
    )
    try:
        optimizer = make_optimizer(spec.method, len(TUNED_NAMES), spec.seed, x0, **settings)
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"method {spec.method} with settings {settings}: {exc}") from exc
    found = fingerprints(spec, scenario, config, settings)
    if scheduler:
        from twin_cosim.optimize.dask_evaluator import check_scheduler

        check_scheduler(scheduler, scheduler_timeout)
    out_dir.mkdir(parents=True, exist_ok=True)
    lock = FolderLock(out_dir)
    try:
        lock.acquire()
    except FolderLockedError as exc:
        optimizer.close()
        raise CampaignError(str(exc)) from None
    try:
        return _run_locked(
            spec,
            out_dir,
            workers,
            scheduler,
            resume,
            progress,
            scenarios,
            config,
            optimizer,
            found,
            scheduler_timeout,
        )
    finally:
        lock.release()


def _run_locked(
    spec: CampaignSpec,
    out_dir: Path,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    progress: bool,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    optimizer,
    found: dict[str, str],
    scheduler_timeout: float | None,
) -> CampaignResult:
    log = evaluator = None
    try:
        header = _prepare(spec, out_dir, resume, scenarios, config, found)
        log = EvaluationLog(out_dir / "evaluations.jsonl")
        robust = header.get("robust") or {}
        cases = header.get("cases") or []
        objective_spec = ObjectiveSpec(
            scenarios,
            spec.fmu,
            header["iau_limit"],
            tuple(c["iau_limit"] for c in cases),
            tuple(robust.get("samples") or ()),
            spec.aggregate,
            tuple(c["scale"] for c in cases),
        )
        early_stop = spec.early_stop and _early_stop_exact(spec.method, scenarios)
        evaluator = make_evaluator(objective_spec, workers, scheduler, scheduler_timeout)
    except BaseException:
        optimizer.close()
        if log is not None:
            log.close()
        raise
    logged_before = {entry["key"] for entry in log.entries}
    start = time.perf_counter()
    bar = tqdm(total=optimizer.budget, unit="eval", disable=not progress, desc=spec.method)
    reused = 0
    try:
        while optimizer.stop_reason is None:
            unit = optimizer.ask()
            if len(unit) == 0:
                break
            candidates = config.from_unit(unit)
            fitness = np.empty(len(candidates))
            missing = []
            for i, x in enumerate(candidates):
                entry = log.lookup(x)
                if entry is None or (
                    entry["status"] == "stopped" and entry["generation"] != optimizer.generation
                ):  # a lower bound holds only against its own generation's cutoff
                    missing.append(i)
                else:
                    fitness[i] = entry["fitness"]
                    reused += entry["key"] in logged_before
            bar.update(len(candidates) - len(missing))
            unique = {}
            for i in missing:
                unique.setdefault(candidate_key(candidates[i]), []).append(i)
            firsts = [rows[0] for rows in unique.values()]
            known = [i for i in range(len(candidates)) if i not in missing]
            group = evaluator.workers if early_stop else max(1, len(firsts))
            for start_at in range(0, len(firsts), group):
                chosen = firsts[start_at : start_at + group]
                cutoff = (
                    elite_cutoff(optimizer, len(candidates), fitness[known])
                    if early_stop
                    else float("inf")
                )
                tasks = [EvaluationTask(candidates[i], cutoff) for i in chosen]
                for j, result in evaluator.imap(tasks):
                    entry = log.append(candidates[chosen[j]], result, optimizer.generation)
                    if result["status"] != "ok":
                        LOG.info(
                            "candidate %s: %s (%s)", entry["x"], result["status"], result["reason"]
                        )
                    rows = unique[entry["key"]]
                    fitness[rows] = result["fitness"]
                    known += rows
                    bar.update(len(rows))
            optimizer.tell(fitness)
            _write_progress(out_dir, optimizer, config, time.perf_counter() - start)
            best = optimizer.best[1]
            bar.set_postfix(gen=optimizer.generation, best_um=f"{best:.3f}")
    except SchedulerError as exc:
        raise CampaignError(
            f"{exc}; every completed evaluation is in {log.path}: continue with --resume {out_dir}"
        ) from exc
    finally:
        bar.close()
        evaluator.close()
        log.close()
        optimizer.close()
    best_unit, best_fitness = optimizer.best
    best_x = config.from_unit(best_unit)
    best_entry = log.lookup(best_x)
    result = CampaignResult(
        method=spec.method,
        best_params=TunedParameters.from_array(best_x).as_dict(),
        fitness=best_fitness,
        status=best_entry["status"],
        metrics=best_entry["metrics"],
        evaluations=optimizer.evaluations,
        evaluations_reused=reused,
        generations=optimizer.generation,
        stop_reason=optimizer.stop_reason or "",
        wall_s=time.perf_counter() - start,
        reference=header["reference"]["metrics"],
        out_dir=str(out_dir),
    )
    (out_dir / "result.json").write_text(json.dumps(result.as_dict(), indent=2) + "\n")
    return result


def _early_stop_exact(method: str, scenarios: tuple[Scenario, ...]) -> bool:
    """Whether the method and every scenario's objective window allow exact early stopping."""
    return method in EXACT_METHODS and all(
        window_spans_run(load_config(s).window, s.reference.duration) for s in scenarios
    )


def _write_progress(out_dir: Path, optimizer, config: OptimizeConfig, elapsed: float) -> None:
    best_unit, best_fitness = optimizer.best
    progress = {
        "generation": optimizer.generation,
        "evaluations": optimizer.evaluations,
        "best_fitness_um": best_fitness,
        "best_params": TunedParameters.from_array(config.from_unit(best_unit)).as_dict(),
        "elapsed_s": elapsed,
    }
    partial = out_dir / "progress.json.partial"
    partial.write_text(json.dumps(progress, indent=2) + "\n")
    partial.replace(out_dir / "progress.json")


def convergence(out_dir: Path) -> np.ndarray:
    """Best fitness so far (um) after each logged evaluation, in log order."""
    entries = EvaluationLog(Path(out_dir) / "evaluations.jsonl")
    fitness = np.array([e["fitness"] for e in entries.entries])
    entries.close()
    return np.minimum.accumulate(fitness) if len(fitness) else fitness
