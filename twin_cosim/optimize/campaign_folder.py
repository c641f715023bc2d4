"""A campaign's folder: its record, the checks of a resume, progress and result files.

A campaign folder holds

- ``campaign.json``: what was asked (scenario, method, seed, budget, settings, bounds, the
  Fine-Tune reference metrics and the IAU limit; per case, a scenario on a plant sample, its
  reference run, IAU limit and E_pk scale; for a calibrated or robust campaign also the plant
  parameters, the scenarios and the plant samples, which a resume checks against the files as
  they are now); ``--resume`` reads it back;
- ``evaluations.jsonl``: every completed evaluation, flushed at once (the checkpoint; see
  :mod:`twin_cosim.optimize.evaluation_log`);
- ``progress.json``: rewritten after every generation (generation, evaluations, best so far);
- ``result.json``: the outcome (best parameters and metrics, evaluations, wall time).

``campaign.json`` also holds content fingerprints of the scenario, the plant FMU and the
settings: a resume whose options or inputs differ is refused, naming what changed.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import MISSING, asdict, fields
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.controller import TunedParameters
from twin_cosim.optimize.algorithms.base import Optimizer
from twin_cosim.optimize.campaign_spec import CampaignError, CampaignResult, CampaignSpec
from twin_cosim.optimize.config import OptimizeConfig
from twin_cosim.optimize.evaluation_log import EvaluationLog
from twin_cosim.optimize.fingerprints import (
    fmu_fingerprint,
    scenario_fingerprint,
    settings_fingerprint,
)
from twin_cosim.scenario import Scenario, load_controller_set

HEADER = "campaign.json"


def read_header(out_dir: Path) -> dict[str, Any]:
    """The record ``campaign.json`` of the campaign in ``out_dir``, checked for its keys."""
    path = Path(out_dir) / HEADER
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


def load_spec(out_dir: Path) -> CampaignSpec:
    """The spec of the campaign stored in ``out_dir`` (for ``--resume``)."""
    stored = read_header(out_dir)["spec"]
    try:
        return CampaignSpec(**stored)
    except TypeError as exc:
        raise CampaignError(f"{Path(out_dir) / HEADER}: bad 'spec': {exc}") from exc


def write_header(
    out_dir: Path,
    spec: CampaignSpec,
    config: OptimizeConfig,
    tuned: TunedParameters,
    found: dict[str, str],
    cases: list[dict[str, Any]],
    robust: dict[str, Any],
) -> dict[str, Any]:
    """Write and return the record of a new campaign.

    ``tuned`` is the scenario's own parameter set (the reference), ``found`` the content
    fingerprints (:func:`fingerprints`), ``cases`` each case's reference, IAU limit (A.s) and
    E_pk scale, ``robust`` the plant parameters, scenarios and plant samples.
    """
    header = {
        "spec": asdict(spec),
        "config": config.as_dict(),
        "reference": {"params": tuned.as_dict(), "metrics": cases[0]["reference"]},
        "iau_limit": cases[0]["iau_limit"],
        "fingerprints": found,
        "cases": cases,
        "robust": robust,
    }
    (out_dir / HEADER).write_text(json.dumps(header, indent=2) + "\n")
    return header


def refuse_a_campaign_in(out_dir: Path) -> None:
    """A new campaign needs a folder that holds none yet."""
    if (out_dir / HEADER).exists():
        raise CampaignError(
            f"{out_dir}: already holds a campaign; use --resume {out_dir} or another --out"
        )


def fingerprints(
    spec: CampaignSpec, scenario: Scenario, config: OptimizeConfig, settings: dict[str, Any]
) -> dict[str, str]:
    """Content fingerprints of the campaign's scenario, plant FMU and settings."""
    fmu = scenario.plant_fmu(spec.fmu)
    if not fmu.is_file() or not zipfile.is_zipfile(fmu):
        raise CampaignError(f"{fmu}: plant FMU not found or not an FMU (zip archive)")
    chosen = {"method": spec.method, "seed": spec.seed, "settings": settings}
    if spec.start is not None:  # the start set's content, not its path
        chosen["start"] = load_controller_set(spec.start).as_dict()
    return {
        "scenario": scenario_fingerprint(scenario),
        "plant_fmu": fmu_fingerprint(fmu),
        "settings": settings_fingerprint({**chosen, "config": config.as_dict()}),
    }


def check_same_options(out_dir: Path, header: dict[str, Any], spec: CampaignSpec) -> None:
    """Refuse a resume whose options differ from the stored campaign's, naming them.

    The scenario and the plant FMU may be given under other paths: their contents are checked
    (:func:`check_same_inputs`).
    """
    defaults = {f.name: f.default for f in fields(CampaignSpec) if f.default is not MISSING}
    stored = {k: v for k, v in header["spec"].items() if k not in ("scenario", "fmu")}
    given = {k: v for k, v in asdict(spec).items() if k not in ("scenario", "fmu")}
    differ = {  # a campaign stored before an option existed has that option's default
        k: (given.get(k, defaults.get(k)), stored.get(k, defaults.get(k)))
        for k in sorted(set(given) | set(stored))
        if given.get(k, defaults.get(k)) != stored.get(k, defaults.get(k))
    }
    if differ:
        raise CampaignError(
            f"{out_dir}: holds a different campaign; options differ from the stored campaign "
            f"(given, stored): {differ}"
        )


def check_same_inputs(
    out_dir: Path,
    header: dict[str, Any],
    spec: CampaignSpec,
    found: dict[str, str],
    robust: dict[str, Any],
) -> None:
    """Refuse a resume whose input contents differ from the stored campaign's.

    ``found`` are the inputs' content fingerprints now (:func:`fingerprints`), ``robust`` their
    plant parameters, scenarios and plant samples now (paths aside: a moved file resumes).
    """
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
    stored = header.get("robust") or {}
    changed = sorted(k for k in robust if k != "scenarios" and stored.get(k) != robust[k])
    if changed:
        raise CampaignError(
            f"{out_dir}: the campaign's {changed} changed since it started (plant parameter "
            "file or robust settings); start a new campaign"
        )


def write_progress(
    out_dir: Path, optimizer: Optimizer, config: OptimizeConfig, elapsed: float
) -> None:
    """Rewrite ``progress.json`` (atomically): generation, evaluations, best so far, time (s)."""
    best_unit, best_fitness = optimizer.best
    progress = {
        "generation": optimizer.generation,
        "evaluations": optimizer.evaluations,
        "best_fitness_um": best_fitness,
        "best_params": config.parameters(config.from_unit(best_unit)),
        "elapsed_s": elapsed,
    }
    partial = out_dir / "progress.json.partial"
    partial.write_text(json.dumps(progress, indent=2) + "\n")
    partial.replace(out_dir / "progress.json")


def write_result(out_dir: Path, result: CampaignResult) -> None:
    """Write ``result.json``."""
    (out_dir / "result.json").write_text(json.dumps(result.as_dict(), indent=2) + "\n")


def logged_fitness(out_dir: Path) -> tuple[np.ndarray, list[str]]:
    """Fitness (um) and status of each logged evaluation, in log order."""
    log = EvaluationLog(Path(out_dir) / "evaluations.jsonl")
    entries = log.entries
    log.close()
    return np.array([e["fitness"] for e in entries], dtype=float), [e["status"] for e in entries]
