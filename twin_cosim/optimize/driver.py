"""The campaign driver: run (or resume) a campaign over a problem and write its folder.

A problem (:class:`Problem`: a single axis' parameters on its scenarios,
:class:`~twin_cosim.optimize.axis_problem.AxisProblem`, or every axis' of a machine on its
circles or a part program, :class:`~twin_cosim.contour.tuning.MachineProblem`) says what is
tuned (names, bounds, start), on which cases, how a worker evaluates a candidate with a cutoff
and what the campaign's record and result hold; the driver knows nothing else of it. It asks
the optimizer for generations in the unit cube, answers each from the evaluation log or the
evaluator, with exact early stopping where the method and the objective allow it
(:mod:`twin_cosim.optimize.early_stop`), and keeps the folder (:mod:`twin_cosim.optimize.store`).

Every argument is checked before anything is written, so a mistake never blocks the folder;
while a campaign runs, ``campaign.lock`` keeps a second writer out of the folder. The pool's
processes start before the campaign is prepared and run every run of it (the reference runs of
the cases and the evaluations): with a process pool, this process never loads the plant.
Resuming replays the optimizer from its seed, answering from the log every batch already
evaluated, so a resumed campaign ends exactly where an uninterrupted one would.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from twin_cosim.optimize.algorithms import make_optimizer, method_label
from twin_cosim.optimize.algorithms.base import Optimizer
from twin_cosim.optimize.config import OptimizeConfig, within_bounds
from twin_cosim.optimize.early_stop import EXACT_METHODS, EarlyStop, GenerationValues
from twin_cosim.optimize.evaluators import (
    Evaluator,
    ReferenceRuns,
    SchedulerError,
    check_scheduler,
    make_evaluator,
)
from twin_cosim.optimize.store import (
    CampaignError,
    EvaluationLog,
    FolderLock,
    candidate_key,
    check_same_options,
    read_record,
    refuse_a_campaign_in,
    write_progress,
    write_record,
    write_result,
)
from twin_cosim.workers import ProcessPool, SerialPool, WorkerFactory, check_workers, make_pool

LOG = logging.getLogger(__name__)


class Problem(Protocol):
    """What a campaign tunes and how a candidate is scored: all the driver knows of it.

    Attributes
    ----------
    spec
        What was asked (a dataclass with at least ``method``, ``seed``, ``budget``,
        ``early_stop``; stored as ``campaign.json``'s ``spec``).
    config : OptimizeConfig
        The tuned dimensions' names and bounds, the error band, the penalty and the method
        settings of the problem's ``optimize`` section.
    case_count : int
        The runs of every candidate (each with its reference run).
    record_keys : Mapping
        The keys (and their types) the problem's ``campaign.json`` holds besides ``spec``.
    prepare_worker : callable
        What a pool's process runs as it starts (imports what its objective needs).
    """

    spec: Any
    config: OptimizeConfig
    case_count: int
    record_keys: Mapping[str, type]
    prepare_worker: Callable[[], None]

    def start(self) -> np.ndarray:
        """The candidate the search starts from (physical units; used when inside the bounds)."""
        ...

    def method_settings(self) -> dict[str, Any]:
        """The optimizer's settings (:func:`~twin_cosim.optimize.algorithms.method_settings`)."""
        ...

    def fingerprints(self, settings: dict[str, Any]) -> dict[str, Any]:
        """The content fingerprints of the inputs and ``settings`` (stored in the record)."""
        ...

    def check_stored(self, out_dir: Path, record: dict[str, Any], found: dict[str, Any]) -> None:
        """Refuse (:class:`CampaignError`) a resume whose inputs differ from the stored record's
        (``found``: the fingerprints now)."""
        ...

    def objective(self, record: dict[str, Any] | None) -> WorkerFactory:
        """The picklable recipe of the
        :class:`~twin_cosim.optimize.evaluators.ProblemObjective` a worker builds (``build()``);
        ``record`` is the campaign's record (its cases' references: IAU caps, scales), None for
        the reference runs."""
        ...

    def new_record(self, references: list[dict[str, Any]], found: dict[str, Any]) -> dict:
        """The record (``campaign.json``) of a new campaign from each case's reference run and the
        fingerprints."""
        ...

    def cutoff_is_exact(self) -> bool:
        """Whether a cutoff on the objective is exact (a method's elite cutoff may stop runs)."""
        ...

    def best(self, x: np.ndarray, record: dict[str, Any]) -> dict[str, Any]:
        """What ``result.json`` says of the best candidate ``x`` (physical units) beyond the
        driver's: ``best_params``, ``reference`` and any details of the problem."""
        ...


@dataclass
class CampaignResult:
    """Outcome of a campaign (also written to ``result.json``).

    Attributes
    ----------
    method : str
        The optimizer's name.
    best_params : dict
        The best candidate by name, physical units (:meth:`Problem.best`).
    fitness : float
        Its fitness, um (the objective's value, plus any penalty).
    status : str
        Its status (ok, violation, ...).
    metrics : dict or None
        Its metrics, as its objective reports them.
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
    reference : dict or list
        The reference runs' values (the problem's own sets).
    out_dir : str
        The campaign folder.
    details : dict
        What else the problem says of the best candidate (:meth:`Problem.best`), written beside
        the fields above.
    """

    method: str
    best_params: dict[str, Any]
    fitness: float
    status: str
    metrics: dict[str, Any] | None
    evaluations: int
    evaluations_reused: int
    generations: int
    stop_reason: str
    wall_s: float
    reference: Any
    out_dir: str
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form: the fields, the details among them."""
        fields = asdict(self)
        details = fields.pop("details")
        return {**fields, **details}


def run_campaign(
    problem: Problem,
    out_dir: Path,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    scheduler_timeout: float | None = None,
    pool: SerialPool | ProcessPool | None = None,
) -> CampaignResult:
    """Run (or resume) a campaign over ``problem`` and write its folder; the result is
    ``result.json``'s.

    Parameters
    ----------
    problem
        What to tune: a single axis' (:class:`~twin_cosim.optimize.axis_problem.AxisProblem`)
        or a machine's (:class:`~twin_cosim.contour.tuning.MachineProblem`).
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
    stored = _check_arguments(problem, out_dir, workers, resume)
    if scheduler:
        check_scheduler(scheduler, scheduler_timeout)
    start_evaluator = partial(
        make_evaluator, scheduler=scheduler, scheduler_timeout=scheduler_timeout
    )
    own = pool is None
    if pool is None:
        pool = SerialPool() if scheduler else make_pool(None, workers, problem.prepare_worker)
    try:
        return _prepared(problem, out_dir, stored, pool, start_evaluator, progress)
    finally:
        if own:
            pool.close()


def _check_arguments(
    problem: Problem, out_dir: Path, workers: int | None, resume: bool
) -> dict[str, Any] | None:
    """Every argument, checked before anything is written; the stored record of a resume."""
    spec = problem.spec
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
    stored = read_record(out_dir, problem.record_keys)
    check_same_options(out_dir, stored, spec)
    return stored


def _prepared(
    problem: Problem,
    out_dir: Path,
    stored: dict[str, Any] | None,
    pool: SerialPool | ProcessPool,
    start_evaluator: Callable[[WorkerFactory, SerialPool | ProcessPool], Evaluator],
    progress: bool,
) -> CampaignResult:
    """The campaign prepared (optimizer, fingerprints, its locked folder), then run;
    ``start_evaluator(recipe, pool)`` starts the evaluator."""
    settings = problem.method_settings()
    optimizer = _make_optimizer(problem, settings)
    try:
        found = problem.fingerprints(settings)
        out_dir.mkdir(parents=True, exist_ok=True)
        lock = FolderLock(out_dir)
        lock.acquire()
    except BaseException:
        optimizer.close()
        raise
    try:
        return _run_locked(
            problem, out_dir, stored, found, optimizer, pool, start_evaluator, progress
        )
    finally:
        lock.release()


def _make_optimizer(problem: Problem, settings: dict[str, Any]) -> Optimizer:
    """The optimizer, started from the problem's start when it lies inside the bounds."""
    config, spec = problem.config, problem.spec
    start = problem.start()
    x0 = config.to_unit(start) if within_bounds(config, start) else None
    try:
        return make_optimizer(spec.method, len(config.names), spec.seed, x0, **settings)
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"method {spec.method} with settings {settings}: {exc}") from exc


def _run_locked(
    problem: Problem,
    out_dir: Path,
    stored: dict[str, Any] | None,
    found: dict[str, Any],
    optimizer: Optimizer,
    pool: SerialPool | ProcessPool,
    start_evaluator: Callable[[WorkerFactory, SerialPool | ProcessPool], Evaluator],
    progress: bool,
) -> CampaignResult:
    """The campaign in its locked folder: its record (reference runs on ``pool``), log and
    evaluator, the loop, the result."""
    spec = problem.spec
    log = None
    try:
        record = _record(problem, out_dir, stored, found, pool)
        log = EvaluationLog(out_dir / "evaluations.jsonl")
        exact = spec.method in EXACT_METHODS and problem.cutoff_is_exact()
        early_stop = EarlyStop(optimizer, spec.early_stop and exact)
        evaluator = start_evaluator(problem.objective(record), pool)
        try:
            loop = AskTellLoop(optimizer, problem.config, log, evaluator, early_stop, progress)
        except BaseException:
            evaluator.close()
            raise
    except BaseException:
        optimizer.close()
        if log is not None:
            log.close()
        raise
    wall_s = loop.run(out_dir)
    best_unit, best_fitness = optimizer.best
    best_x = problem.config.from_unit(best_unit)
    best_entry = log.lookup(best_x)
    result = CampaignResult(
        method=spec.method,
        fitness=best_fitness,
        status=best_entry["status"],
        metrics=best_entry["metrics"],
        evaluations=optimizer.evaluations,
        evaluations_reused=loop.reused,
        generations=optimizer.generation,
        stop_reason=optimizer.stop_reason or "",
        wall_s=wall_s,
        out_dir=str(out_dir),
        **problem.best(best_x, record),
    )
    write_result(out_dir, result.as_dict())
    return result


def _record(
    problem: Problem,
    out_dir: Path,
    stored: dict[str, Any] | None,
    found: dict[str, Any],
    pool: SerialPool | ProcessPool,
) -> dict[str, Any]:
    """The stored record checked against the inputs as they are now, or a new campaign's (its
    cases' reference runs on ``pool``)."""
    if stored is not None:
        problem.check_stored(out_dir, stored, found)
        return stored
    refuse_a_campaign_in(out_dir)
    answered = dict(pool.imap(range(problem.case_count), ReferenceRuns(problem.objective(None))))
    record = problem.new_record([answered[case] for case in range(problem.case_count)], found)
    write_record(out_dir, record)
    return record


class AskTellLoop:
    """Asks the optimizer for generations, answers each from the log or the evaluator, tells it.

    Parameters
    ----------
    optimizer
        The optimizer, in the unit cube.
    config
        The problem's dimensions (bounds: unit cube <-> physical units).
    log
        The campaign's evaluation log: read for answers, appended with every new result.
    evaluator
        Scores the candidates the log cannot answer.
    early_stop
        The campaign's early stopping (on or off): the cutoffs, passes and order of each
        generation.
    progress
        Show a progress bar (evaluations) on stderr.
    """

    def __init__(
        self,
        optimizer: Optimizer,
        config: OptimizeConfig,
        log: EvaluationLog,
        evaluator: Evaluator,
        early_stop: EarlyStop,
        progress: bool,
    ) -> None:
        from tqdm import tqdm  # the command's process only (a worker may import this module)

        self.optimizer = optimizer
        self.config = config
        self.log = log
        self.evaluator = evaluator
        self.early_stop = early_stop
        self.logged_before = {entry["key"] for entry in log.entries}
        self.reused = 0  # answers from entries logged before this run
        self.bar = tqdm(
            total=optimizer.budget,
            unit="eval",
            disable=not progress,
            desc=method_label(optimizer.name),
        )

    def run(self, out_dir: Path) -> float:
        """Ask and tell until the optimizer stops (the log synced to disk and ``progress.json``
        written after every generation), then free the evaluator, the log and the optimizer.

        Returns
        -------
        float
            The loop's wall time (s, until everything is freed).

        Raises
        ------
        CampaignError
            When the Dask scheduler is lost; the message tells how to resume.
        """
        start = time.perf_counter()
        optimizer = self.optimizer
        try:
            while optimizer.stop_reason is None:
                unit = optimizer.ask()
                if len(unit) == 0:
                    break
                optimizer.tell(self._generation(self.config.from_unit(unit)))
                self.log.sync()
                write_progress(out_dir, optimizer, self.config, time.perf_counter() - start)
                self.bar.set_postfix(gen=optimizer.generation, best_um=f"{optimizer.best[1]:.3f}")
        except SchedulerError as exc:
            raise CampaignError(
                f"{exc}; every completed evaluation is in {self.log.path}: continue with "
                f"--resume {out_dir}"
            ) from exc
        finally:
            self.bar.close()
            self.evaluator.close()
            self.log.close()
            optimizer.close()
        return time.perf_counter() - start

    def _generation(self, candidates: np.ndarray) -> np.ndarray:
        """The fitness (um) of every candidate of a generation (physical units, one per row):
        from the log where it answers, else evaluated in the passes of early stopping."""
        values = GenerationValues(len(candidates))
        missing = self._answer_from_log(candidates, values)
        for rows, guess, again in self.early_stop.passes(values, missing):
            self._evaluate(candidates, rows, values, guess, again)
        return values.fitness

    def _evaluate(
        self,
        candidates: np.ndarray,
        rows: list[int],
        values: GenerationValues,
        guess: float,
        again: bool,
    ) -> None:
        """Evaluate ``rows`` of ``candidates`` (duplicates once) with cutoffs at most ``guess``
        (um), as many out at a time as early stopping asks; log them and fill their ``values``.
        Rows evaluated ``again`` are not counted by the progress bar a second time."""
        unique: dict[str, list[int]] = {}
        for i in rows:
            unique.setdefault(candidate_key(candidates[i]), []).append(i)
        firsts = [same[0] for same in unique.values()]
        firsts = [
            firsts[k] for k in self.early_stop.order(candidates[firsts], self.log, self.config)
        ]
        tasks = self.early_stop.tasks(candidates[firsts], values, guess)
        in_flight = self.early_stop.in_flight(self.evaluator.workers, self.evaluator.ahead)
        for j, result in self.evaluator.imap(tasks, in_flight):
            entry = self.log.append(candidates[firsts[j]], result, self.optimizer.generation)
            if result["status"] != "ok":
                LOG.info("candidate %s: %s (%s)", entry["x"], result["status"], result["reason"])
            same = unique[entry["key"]]
            values.set(same, result)
            if not again:
                self.bar.update(len(same))

    def _answer_from_log(self, candidates: np.ndarray, values: GenerationValues) -> list[int]:
        """Fill ``values`` (a stopped candidate's lower bound too) from the log where it answers;
        the rows it does not answer."""
        missing = []
        for i, x in enumerate(candidates):
            entry = self.log.lookup(x)
            if entry is None or (
                entry["status"] == "stopped" and entry["generation"] != self.optimizer.generation
            ):  # a lower bound holds only against its own generation's cutoff
                missing.append(i)
            else:
                values.set([i], entry)
                self.reused += entry["key"] in self.logged_before
        self.bar.update(len(candidates) - len(missing))
        return missing
