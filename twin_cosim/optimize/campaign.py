"""Optimizer campaigns: run (or resume) one and write its folder.

The pieces: what is asked and found (:mod:`~twin_cosim.optimize.campaign_spec`), the cases of
the resolved scenarios on plant samples (:mod:`~twin_cosim.optimize.cases`), the folder and the
checks of a resume (:mod:`~twin_cosim.optimize.campaign_folder`) and the ask/tell loop
(:mod:`~twin_cosim.optimize.campaign_loop`). Every argument is checked before anything is
written, so a mistake never blocks the folder; while a campaign runs, ``campaign.lock`` keeps a
second writer out of the folder. The pool's processes start before the campaign is prepared and
run every run of it (the reference runs and the evaluations): with a process pool, this process
never loads the plant.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.optimize.algorithms import make_optimizer
from twin_cosim.optimize.algorithms.base import Optimizer
from twin_cosim.optimize.campaign_folder import (
    check_same_inputs,
    check_same_options,
    fingerprints,
    read_header,
    refuse_a_campaign_in,
    write_header,
    write_result,
)
from twin_cosim.optimize.campaign_loop import run_loop
from twin_cosim.optimize.campaign_spec import CampaignError, CampaignResult, CampaignSpec
from twin_cosim.optimize.cases import (
    campaign_scenarios,
    case_references,
    early_stop_exact,
    objective_spec,
    robust_settings,
)
from twin_cosim.optimize.config import OptimizeConfig, load_config, within_bounds
from twin_cosim.optimize.evaluation_log import EvaluationLog
from twin_cosim.optimize.evaluator_protocol import Evaluator
from twin_cosim.optimize.evaluators import make_evaluator
from twin_cosim.optimize.folder_lock import FolderLock, FolderLockedError
from twin_cosim.optimize.worker_specs import ObjectiveSpec
from twin_cosim.pool_runs import prepare_campaign_worker
from twin_cosim.scenario import Scenario
from twin_cosim.workers import ProcessPool, SerialPool, check_workers, make_pool


def run_campaign(
    spec: CampaignSpec,
    out_dir: Path,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    scheduler_timeout: float | None = None,
    scenarios: tuple[Scenario, ...] | None = None,
    pool: SerialPool | ProcessPool | None = None,
) -> CampaignResult:
    """Run (or resume) a campaign and write its folder.

    Parameters
    ----------
    spec
        What to optimize.
    out_dir
        Campaign folder.
    workers
        Local processes (1: serial in this process; None: all cores); ignored with ``pool``.
    scheduler
        Dask scheduler address: the evaluations run there (the reference runs in ``pool``, or in
        this process).
    resume
        Continue the campaign already in ``out_dir``.
    progress
        Show a progress bar on stderr.
    scheduler_timeout
        Seconds to wait for the Dask scheduler to answer, and again for a worker to join.
    scenarios
        The spec's scenarios as :func:`~twin_cosim.optimize.cases.campaign_scenarios` resolves
        them, when the caller has them already; resolved here when None.
    pool
        A started local pool (:mod:`twin_cosim.workers`), shared with the caller, who closes it:
        the reference runs and (without ``scheduler``) the evaluations run on its workers. None:
        a pool of ``workers`` is started here at once (its processes start while the campaign
        is prepared) and closed at the end.

    Raises
    ------
    CampaignError
        On a bad argument (before anything is written), a folder in use by another process, or
        a resume whose options or inputs differ from the stored campaign.
    """
    out_dir = Path(out_dir)
    stored = _check_arguments(spec, out_dir, workers, resume)
    start_evaluator = _evaluators(scheduler, scheduler_timeout)
    own = pool is None
    if pool is None:
        pool = SerialPool() if scheduler else make_pool(None, workers, prepare_campaign_worker)
    try:
        return _prepared(spec, out_dir, stored, scenarios, pool, start_evaluator, progress)
    finally:
        if own:
            pool.close()


def _prepared(
    spec: CampaignSpec,
    out_dir: Path,
    stored: dict[str, Any] | None,
    scenarios: tuple[Scenario, ...] | None,
    pool: SerialPool | ProcessPool,
    start_evaluator: Callable[[ObjectiveSpec, SerialPool | ProcessPool], Evaluator],
    progress: bool,
) -> CampaignResult:
    """The campaign prepared (scenarios, optimizer, fingerprints, its locked folder), then run;
    ``start_evaluator(objective, pool)`` starts the evaluator."""
    if scenarios is None:
        scenarios = campaign_scenarios(spec)
    config = load_config(scenarios[0])
    settings = _method_settings(spec, config)
    optimizer = _make_optimizer(spec, config, scenarios[0], settings)
    found = fingerprints(spec, scenarios[0], config, settings)
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
            stored,
            scenarios,
            config,
            found,
            optimizer,
            pool,
            start_evaluator,
            progress,
        )
    finally:
        lock.release()


def _check_arguments(
    spec: CampaignSpec, out_dir: Path, workers: int | None, resume: bool
) -> dict[str, Any] | None:
    """Every argument, checked before anything is written; the stored record of a resume."""
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
    if not resume:
        return None
    stored = read_header(out_dir)
    check_same_options(out_dir, stored, spec)
    return stored


def _evaluators(
    scheduler: str | None, scheduler_timeout: float | None
) -> Callable[[ObjectiveSpec, SerialPool | ProcessPool], Evaluator]:
    """What starts the campaign's evaluator from the objective and the local pool; a Dask
    scheduler is checked here, at once."""
    if scheduler:  # Dask is an optional extra: imported only when asked for
        from twin_cosim.optimize.dask_evaluator import check_scheduler

        check_scheduler(scheduler, scheduler_timeout)
    return partial(make_evaluator, scheduler=scheduler, scheduler_timeout=scheduler_timeout)


def _method_settings(spec: CampaignSpec, config: OptimizeConfig) -> dict[str, Any]:
    """The method's settings: the scenario's, the spec's on top, and the spec's budget."""
    settings = {**config.methods.get(spec.method, {}), **spec.settings}
    if spec.budget is not None:
        settings["budget"] = spec.budget
    return settings


def _make_optimizer(
    spec: CampaignSpec, config: OptimizeConfig, scenario: Scenario, settings: dict[str, Any]
) -> Optimizer:
    """The optimizer, started from the scenario's parameters when they lie inside the bounds."""
    x0 = (
        config.to_unit(scenario.tuned.as_array()) if within_bounds(config, scenario.tuned) else None
    )
    try:
        return make_optimizer(spec.method, len(TUNED_NAMES), spec.seed, x0, **settings)
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"method {spec.method} with settings {settings}: {exc}") from exc


def _run_locked(
    spec: CampaignSpec,
    out_dir: Path,
    stored: dict[str, Any] | None,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    found: dict[str, str],
    optimizer: Optimizer,
    pool: SerialPool | ProcessPool,
    start_evaluator: Callable[[ObjectiveSpec, SerialPool | ProcessPool], Evaluator],
    progress: bool,
) -> CampaignResult:
    """The campaign in its locked folder: its record (reference runs on ``pool``), log and
    evaluator, the loop, the result."""
    log = None
    try:
        header = _header(spec, out_dir, stored, scenarios, config, found, pool)
        log = EvaluationLog(out_dir / "evaluations.jsonl")
        early_stop = spec.early_stop and early_stop_exact(spec.method, scenarios)
        evaluator = start_evaluator(objective_spec(spec, scenarios, header), pool)
    except BaseException:
        optimizer.close()
        if log is not None:
            log.close()
        raise
    reused, wall_s = run_loop(optimizer, config, log, evaluator, early_stop, out_dir, progress)
    result = _result(spec, out_dir, header, config, optimizer, log, reused, wall_s)
    write_result(out_dir, result)
    return result


def _result(
    spec: CampaignSpec,
    out_dir: Path,
    header: dict[str, Any],
    config: OptimizeConfig,
    optimizer: Optimizer,
    log: EvaluationLog,
    reused: int,
    wall_s: float,
) -> CampaignResult:
    """The outcome of a finished loop: the best candidate, its log entry, the counts, the time.

    ``reused`` counts the evaluations answered from entries logged before this run, ``wall_s``
    is the loop's wall time (s).
    """
    best_unit, best_fitness = optimizer.best
    best_x = config.from_unit(best_unit)
    best_entry = log.lookup(best_x)
    return CampaignResult(
        method=spec.method,
        best_params=TunedParameters.from_array(best_x).as_dict(),
        fitness=best_fitness,
        status=best_entry["status"],
        metrics=best_entry["metrics"],
        evaluations=optimizer.evaluations,
        evaluations_reused=reused,
        generations=optimizer.generation,
        stop_reason=optimizer.stop_reason or "",
        wall_s=wall_s,
        reference=header["reference"]["metrics"],
        out_dir=str(out_dir),
    )


def _header(
    spec: CampaignSpec,
    out_dir: Path,
    stored: dict[str, Any] | None,
    scenarios: tuple[Scenario, ...],
    config: OptimizeConfig,
    found: dict[str, str],
    pool: SerialPool | ProcessPool,
) -> dict[str, Any]:
    """The stored record checked against the inputs as they are now, or a new campaign's (its
    reference runs on ``pool``)."""
    robust = robust_settings(spec, scenarios)
    if stored is not None:
        check_same_inputs(out_dir, stored, spec, found, robust)
        return stored
    refuse_a_campaign_in(out_dir)
    cases = case_references(spec, scenarios, config, robust["samples"], pool)
    return write_header(out_dir, spec, config, scenarios[0].tuned, found, cases, robust)
