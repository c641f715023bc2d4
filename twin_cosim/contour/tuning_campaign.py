"""A machine's tuning campaign: every axis' parameters tuned on circles or a part program.

The campaign machinery of one axis, reused: the optimizers (ask/tell in the unit cube), the
evaluators (serial, process pool), the ask/tell loop with exact early stopping
(:mod:`twin_cosim.optimize.campaign_loop`), the evaluation log that is the checkpoint
(``--resume`` replays the optimizer from its seed, answering from the log) and the folder lock.
The objective is :class:`~twin_cosim.contour.tuning.ContourObjective`. The folder holds
``campaign.json`` (spec, bounds, fingerprints of the machine file, the program and the FMUs,
each case's reference values), ``evaluations.jsonl``, ``progress.json`` and ``result.json``
(``best_params`` with ``axes``: ``twin circle --params result.json`` takes it).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.contour.gcode import read_program
from twin_cosim.contour.tuning import (
    ContourObjectiveSpec,
    ContourSettings,
    axes_tuned,
    cases_of,
    contour_settings,
    machine_vector,
)
from twin_cosim.optimize.algorithms import make_optimizer
from twin_cosim.optimize.campaign_loop import run_loop
from twin_cosim.optimize.campaign_spec import CampaignError
from twin_cosim.optimize.early_stop import EXACT_METHODS
from twin_cosim.optimize.evaluation_log import EvaluationLog
from twin_cosim.optimize.evaluators import make_evaluator
from twin_cosim.optimize.fingerprints import fmu_fingerprint, settings_fingerprint
from twin_cosim.optimize.folder_lock import FolderLock, FolderLockedError
from twin_cosim.scenario import load_axes_parameters, load_machine
from twin_cosim.scenario.machine import MachineScenario
from twin_cosim.workers import make_pool

HEADER = "campaign.json"


@dataclass(frozen=True)
class ContourCampaignSpec:
    """What a machine's campaign optimizes and how (stored in ``campaign.json``).

    Attributes
    ----------
    scenario : str
        Machine scenario file (its ``optimize`` section).
    method : str
        Optimizer name.
    seed : int
        Its seed.
    budget : int or None
        Most evaluations; the method's default when None.
    program : str or None
        Part program to tune on instead of the circles.
    target : str or None
        ``G``, ``spike`` or ``contour``; the scenario's when None.
    early_stop : bool
        Stop candidates early where that is exact.
    start : str or None
        Sets the search starts from (a Table 3 set or a file, as ``--params``: one set or one
        per axis); the scenario's own when None. The reference of the relative scores and of
        the IAU caps stays the scenario's own sets.
    """

    scenario: str
    method: str
    seed: int = 0
    budget: int | None = None
    program: str | None = None
    target: str | None = None
    early_stop: bool = True
    start: str | None = None


def _fingerprints(machine: MachineScenario, spec: ContourCampaignSpec, settings) -> dict:
    program = b"" if spec.program is None else Path(spec.program).read_bytes()
    start = (
        b""
        if spec.start is None or not Path(spec.start).is_file()
        else Path(spec.start).read_bytes()
    )
    return {
        "scenario": hashlib.sha256(Path(machine.source).read_bytes()).hexdigest(),
        "program": hashlib.sha256(program).hexdigest(),
        "start": hashlib.sha256(start).hexdigest(),
        "plant_fmus": {a.name: fmu_fingerprint(a.plant_fmu()) for a in machine.axes},
        "settings": settings_fingerprint({"spec": asdict(spec), "settings": settings}),
    }


def _header(
    out_dir: Path,
    spec: ContourCampaignSpec,
    objective: ContourObjectiveSpec,
    found: dict,
    resume: bool,
) -> dict[str, Any]:
    """The stored record checked against the inputs (a resume), or a new campaign's."""
    path = out_dir / HEADER
    if resume:
        if not path.is_file():
            raise CampaignError(f"{out_dir}: no campaign.json to resume from")
        stored = json.loads(path.read_text())
        given = {k: v for k, v in asdict(spec).items() if k != "scenario"}
        kept = {k: v for k, v in stored["spec"].items() if k != "scenario"}
        if given != kept or stored["fingerprints"] != found:
            raise CampaignError(
                f"{out_dir}: holds a different campaign (options or inputs differ from the "
                f"stored ones: given {given}, stored {kept})"
            )
        return stored
    if path.exists():
        raise CampaignError(f"{out_dir}: already holds a campaign; use --resume or another --out")
    probe = objective.build()
    try:
        references = probe.reference_values()
    finally:
        probe.close()
    for reference in references:
        reference.pop("steps")
    header = {
        "spec": asdict(spec),
        "config": objective.settings.config.as_dict(),
        "target": objective.settings.target,
        "relative": objective.settings.relative,
        "cases": [c.label for c in objective.cases],
        "references": references,
        "reference_params": {a.name: a.tuned.as_dict() for a in objective.machine.axes},
        "fingerprints": found,
    }
    path.write_text(json.dumps(header, indent=2) + "\n")
    return header


def _reference_fitness(header: dict[str, Any]) -> float:
    """The reference sets' fitness (um): the first case's value when relative, else the
    largest."""
    values = [r[header["target"]] for r in header["references"]]
    return values[0] if header["relative"] else max(values)


def run_contour_campaign(
    spec: ContourCampaignSpec,
    out_dir: Path,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
) -> dict[str, Any]:
    """Run (or resume) a machine's campaign; returns (and writes) ``result.json``'s content.

    Raises
    ------
    CampaignError
        On a folder in use, a resume whose options or inputs differ, a bad method setting.
    """
    out_dir = Path(out_dir)
    machine = load_machine(spec.scenario)
    settings: ContourSettings = contour_settings(machine, spec.target)
    if spec.program and settings.target != "contour":
        raise CampaignError(f"target {settings.target}: a part program is tuned on 'contour'")
    program = read_program(spec.program, machine.axis_names) if spec.program else None
    objective = ContourObjectiveSpec(machine, settings, cases_of(settings, program))
    config = settings.config
    method_settings = {**config.methods.get(spec.method, {})}
    if spec.budget is not None:
        method_settings["budget"] = spec.budget
    first = machine
    if spec.start:
        first = machine.with_tuned(load_axes_parameters(spec.start, machine.axis_names))
    x0 = config.to_unit(machine_vector(first))
    x0 = x0 if np.all((x0 >= 0) & (x0 <= 1)) else None
    try:
        optimizer = make_optimizer(spec.method, len(config.names), spec.seed, x0, **method_settings)
    except (TypeError, ValueError) as exc:
        raise CampaignError(f"method {spec.method}: {exc}") from exc
    found = _fingerprints(machine, spec, method_settings)
    out_dir.mkdir(parents=True, exist_ok=True)
    lock = FolderLock(out_dir)
    try:
        lock.acquire()
    except FolderLockedError as exc:
        optimizer.close()
        raise CampaignError(str(exc)) from None
    pool = None
    try:
        try:
            header = _header(out_dir, spec, objective, found, resume)
            objective = ContourObjectiveSpec(
                machine, settings, objective.cases, tuple(header["references"])
            )
            log = EvaluationLog(out_dir / "evaluations.jsonl")
            pool = make_pool(None, workers)
            evaluator = make_evaluator(objective, pool, None)
        except BaseException:
            optimizer.close()
            raise
        early = spec.early_stop and spec.method in EXACT_METHODS
        reused, wall_s = run_loop(optimizer, config, log, evaluator, early, out_dir, progress)
        best_unit, best_fitness = optimizer.best
        best = config.from_unit(best_unit)
        entry = EvaluationLog(out_dir / "evaluations.jsonl")
        logged = entry.lookup(best)
        entry.close()
        result = {
            "method": spec.method,
            "best_params": {"axes": {n: t.as_dict() for n, t in axes_tuned(machine, best).items()}},
            "fitness": best_fitness,
            "status": logged["status"] if logged else "",
            "metrics": logged["metrics"] if logged else None,
            "reference": header["references"],
            "reference_fitness": _reference_fitness(header),
            "cases": header["cases"],
            "target": settings.target,
            "evaluations": optimizer.evaluations,
            "evaluations_reused": reused,
            "generations": optimizer.generation,
            "stop_reason": optimizer.stop_reason or "",
            "wall_s": wall_s,
            "out_dir": str(out_dir),
        }
        (out_dir / "result.json").write_text(json.dumps(result, indent=2) + "\n")
        return result
    finally:
        if pool is not None:
            pool.close()
        lock.release()
