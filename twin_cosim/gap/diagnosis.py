"""The diagnosis pipeline: where the gap lies, which unmodelled effect causes it, how far it
shrinks, what is left, and the calibrated plant.

Stages, each a typed result held by :class:`Diagnosis` to the end (the JSON is one
serialisation of it, :func:`twin_cosim.gap.report.pages.summary`; the pages, the plant files
and the printed verdict are written from its fields):

1. **Context** (:func:`~twin_cosim.gap.data.context.build_context`): the scenario, the plant
   model and its variable ranges, the measured runs checked (outliers repaired and reported)
   and the split: ``--holdout`` runs judge (each following its own reference and disturbance
   when the scenario's reference comes from a measured file, e.g. the EMPS validation run), or
   every measured run is split in time at ``split``. The fit never sees a held-out sample
   (the held-out standstill only confirms the noise harmonics, stage 2).
2. **Replay and noise** (:mod:`twin_cosim.gap.floors.noise`): the twin replays the scenario;
   the measured noise at standstill becomes plant parameters where the held-out standstill
   confirms it; the noise floors (from repeats of
   one input, else from the residual's high-frequency part) normalise all residuals, with their
   source.
3. **Where** (:mod:`twin_cosim.gap.location`): regimes, along the axis, orders and
   frequencies.
4. **Which** (:mod:`twin_cosim.gap.which.selector`): rounds of fits, each looking again at the
   residual left, judged on held-out data against the noise and calibration floors, then the
   cold refits, the swaps and the backward pass.
5. **Verdict and what is left** (:mod:`twin_cosim.gap.verdict`), per held-out run the
   figures before and after (RMS gaps, the benchmark's relative errors).
6. **The calibrated plant** (:func:`calibrated_plant`): the noise harmonics, the kept effects'
   FMU parameters and the calibration correction, each with where it came from (the file
   ``plant.yaml``, :mod:`twin_cosim.scenario.plant_parameters`), and what it still misses on
   the held-out runs, replayed as written (:mod:`twin_cosim.model_error`: the margins of a
   prediction's interval).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin_cosim.cosim import run_scenario
from twin_cosim.gap.data.context import (
    DiagnosisContext,
    build_context,
    estimate_resolution,
    library_for,
    repeated_residuals,
    training_residuals,
)
from twin_cosim.gap.data.regimes import REGIMES, drive_steps
from twin_cosim.gap.data.residuals import (
    Residuals,
    joined,
    pulse_response,
    relative_errors,
    residuals_of,
    validation_figures,
)
from twin_cosim.gap.floors.noise import (
    Floors,
    MetricComparison,
    NoiseModel,
    identify_noise,
    noise_floors,
)
from twin_cosim.gap.location import Location, locate
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.verdict import Remaining, remaining_of, verdict_text
from twin_cosim.gap.which.acceptance import Judging
from twin_cosim.gap.which.replay import (
    TRAINING_CACHE_BYTES,
    JudgingSpec,
    Replays,
    ReplaySpec,
    SimulateTask,
    TrainingData,
)
from twin_cosim.gap.which.replay_pool import JudgingCache, ReplayPool, calibration_moves
from twin_cosim.gap.which.selector import Round, Selection, Selector, Swap
from twin_cosim.measured import MeasuredRun
from twin_cosim.model_error import ModelError
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.plant_parameters import PlantParameters
from twin_cosim.workers import BoundPool, ProcessPool, SerialPool, make_pool, prepare_replay_worker

ProgressFactory = Callable[[int, str], Callable[[int], None]]
# Wording of the verdict only: a rejected hypothesis that cuts the raw held-out gap by this share
# or more is named as explaining it within calibration error (acceptance is the evidence test).
EXPLAINS_SHARE = 0.25
NOISE_SOURCE = "noise harmonics identified at standstill by twin diagnose"
CALIBRATION_SOURCE = (
    "calibration correction of twin diagnose: the best correction within the calibration "
    "tolerance of what the accepted effects leave on the held-out runs (linearised)"
)
JOINT_SOURCE = (
    "joint refit of twin diagnose: the calibrated parameters refitted with the accepted effects "
    "under their prior (the tolerance)"
)


@dataclass(frozen=True)
class HeldOutRun:
    """Figures of one held-out run before and after the accepted effects.

    Attributes
    ----------
    source : str
        The run.
    position_rms_um_before, position_rms_um_after : float
        RMS position gap, um.
    current_rms_before, current_rms_after : float
        RMS current (drive command) gap, A (V).
    relative_errors_before, relative_errors_after : dict
        The benchmark's 100 ||y - y_sim|| / ||y|| (%) of position, velocity, acceleration and
        force.
    pulse_response_before, pulse_response_after : dict or None
        For a run with a disturbance signal: how the acceleration residual concentrates after
        its edges (:func:`twin_cosim.gap.data.residuals.pulse_response`).
    """

    source: str
    position_rms_um_before: float
    position_rms_um_after: float
    current_rms_before: float
    current_rms_after: float
    relative_errors_before: dict[str, float]
    relative_errors_after: dict[str, float]
    pulse_response_before: dict[str, float] | None = None
    pulse_response_after: dict[str, float] | None = None


@dataclass(frozen=True)
class Diagnosis:
    """The stages' results, from the data to the calibrated plant.

    Attributes
    ----------
    context : DiagnosisContext
        The runs, the split and the plant model.
    settings : DiagnosisSettings
        Thresholds and effort.
    noise : NoiseModel
        The noise harmonics kept as plant parameters and those dropped.
    floors : Floors
        The noise floors of the residuals.
    where : Location
        Where the gap lies before the accepted effects (training and held-out data).
    selection : Selection
        The rounds, the accepted effects and their FMU parameters, swaps, cold refits and the
        backward pass.
    significant : bool
        Whether the held-out gap of the nominal twin is significant.
    verdict : str
        The verdict in words.
    remaining : Remaining
        What the accepted effects leave of the held-out gap, and what it was before them.
    remaining_where : Location
        Where what is left lies (held-out data).
    metrics_before, metrics_after : list of MetricComparison
        The held-out figures of merit before and after the accepted effects.
    held_out_runs : list of HeldOutRun
        Per held-out run, its figures before and after.
    validation : dict
        The paper's validation figures of the position gap before the effects, um.
    train_before, holdout_before, holdout_after : Residuals
        The training residual of the nominal twin, and the held-out residual before and after.
    calibrated_plant : PlantParameters
        The calibrated plant (``plant.yaml``), made by the measured and held-out runs, with
        what it still misses on the held-out runs (its ``model_error``; None for open-loop
        runs).
    times : dict
        Where the time went, per phase of the selection and of the diagnosis.
    """

    context: DiagnosisContext
    settings: DiagnosisSettings
    noise: NoiseModel
    floors: Floors
    where: Location
    selection: Selection
    significant: bool
    verdict: str
    remaining: Remaining
    remaining_where: Location
    metrics_before: list[MetricComparison]
    metrics_after: list[MetricComparison]
    held_out_runs: list[HeldOutRun]
    validation: dict[str, float]
    train_before: Residuals
    holdout_before: Residuals
    holdout_after: Residuals
    calibrated_plant: PlantParameters
    times: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def rounds(self) -> list[Round]:
        """The rounds of the selection."""
        return self.selection.rounds

    @property
    def steps(self) -> list[Round]:
        """The rounds that accepted an effect (a group or a pair), in order."""
        return [r for r in self.rounds if r.accepted]

    @property
    def accepted(self) -> list[str | list[str]]:
        """The accepted effects in order: a name, or a group of look-alikes."""
        return [g if len(g) > 1 else g[0] for g in self.selection.accepted]

    @property
    def unexplained_by_regime(self) -> dict[str, float]:
        """Held-out position residual energy left per regime, as a share of what it was."""
        return _unexplained(self.holdout_before, self.holdout_after)

    @property
    def warnings(self) -> list[str]:
        """Problems that did not stop the diagnosis: the runs' and the noise harmonics'."""
        return self.context.warnings + self.noise.dropped


def jsonable(value: Any) -> Any:
    """``value`` ready for JSON (and YAML): mappings with text keys, lists, numpy scalars as
    Python numbers, non-finite floats as None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _unexplained(before: Residuals, after: Residuals) -> dict[str, float]:
    """Held-out position residual energy left per regime, as a share of what it was."""
    shares = {}
    for code, name in enumerate(REGIMES):
        mask = before.regimes == code
        energy = float(np.sum(before.position[mask] ** 2))
        if mask.any() and energy > 0:
            shares[name] = float(np.sum(after.position[mask] ** 2)) / energy
    return shares


def _noise_stage(
    context: DiagnosisContext, level: float
) -> tuple[NoiseModel, dict[str, float], Replays]:
    """Stage 2a: the noise harmonics from the replays of the nominal twin (identified on the
    training data, confirmed on the held-out data at significance ``level``), and the replays
    of the twin with them (in this process: a few replays do not pay for a pool)."""
    with Plant(context.fmu) as plant:

        def replay(parameters: dict[str, float]) -> Replays:
            first = [
                run_scenario(plant, s, plant_overrides=parameters)
                for s in context.training_scenarios
            ]
            judging = [
                next(
                    (r for t, r in zip(context.training_scenarios, first, strict=True) if t is s),
                    None,
                )
                for s in context.judging_scenarios
            ]
            judging = [
                r if r is not None else run_scenario(plant, s, plant_overrides=parameters)
                for r, s in zip(judging, context.judging_scenarios, strict=True)
            ]
            return Replays(first, judging)

        raw = replay(context.nominal)
        held = residuals_of(
            context.judged,
            [raw.judging[k] for k in context.scenario_of_run],
            [context.judging_scenarios[k].reference for k in context.scenario_of_run],
        )
        noise = identify_noise(
            training_residuals(context, raw.training),
            held,
            context.dt,
            context.ranges,
            context.nominal,
            level,
        )
        nominal = {**context.nominal, **noise.plant_parameters}
        return noise, nominal, replay(nominal) if noise.plant_parameters else raw


def diagnose(
    scenario: Scenario,
    measured: list[MeasuredRun],
    holdout: list[MeasuredRun] | None = None,
    fmu: str | None = None,
    settings: DiagnosisSettings | None = None,
    workers: int | None = None,
    progress: ProgressFactory | None = None,
    pool: SerialPool | ProcessPool | None = None,
    replay_cache: bool = True,
) -> Diagnosis:
    """Diagnose the gap between the measured runs and the twin's replay of the scenario.

    Parameters
    ----------
    scenario
        What the runs were measured with (reference, controller, plant).
    measured
        Training runs (all of the scenario's reference).
    holdout
        Judging runs; None or empty: a time split of the measured runs.
    fmu
        Plant FMU (the scenario's when None).
    settings
        Thresholds and effort (the defaults when None).
    workers
        Replay processes (1: in this process; None: all cores); ignored with ``pool``.
    progress
        ``progress(total, label)`` returns a function called with the number of tasks done.
    pool
        A started pool (:mod:`twin_cosim.workers`) for the replays, shared with the caller, who
        closes it; None: one of ``workers`` is started here at once (its processes start while
        this one builds the context and the noise model) and closed at the end.
    replay_cache
        Answer a replay of a parameter set replayed before from the caches (the workers'
        training residuals, the judging replays); False: run every replay (the same results,
        at more cost: for checks and benchmarks).
    """
    settings = settings or DiagnosisSettings()
    if pool is None:
        with make_pool(None, workers, prepare_replay_worker) as own:
            return _diagnose(
                scenario, measured, holdout or [], fmu, settings, progress, own, replay_cache
            )
    return _diagnose(scenario, measured, holdout or [], fmu, settings, progress, pool, replay_cache)


def _diagnose(
    scenario: Scenario,
    measured: list[MeasuredRun],
    holdout: list[MeasuredRun],
    fmu: str | None,
    settings: DiagnosisSettings,
    progress: ProgressFactory | None,
    pool: SerialPool | ProcessPool,
    replay_cache: bool = True,
) -> Diagnosis:
    """:func:`diagnose` with its replays on ``pool``."""
    cpu_start = time.process_time()
    context = build_context(scenario, measured, holdout, fmu, settings)
    calibrated = [n for n in plant_model(context.model).calibrated if n in context.nominal]
    directions = pool.start(  # the first calibration directions, while this process finds noise
        calibration_moves(context.nominal, {}, calibrated, settings.calibration_tolerance),
        JudgingSpec(context.judging_scenarios, str(context.fmu), context.nominal, context.ranges),
    )
    noise, nominal, start = _noise_stage(context, settings.significance_level)
    if directions is not None and nominal != context.nominal:  # the noise model moved the twin
        directions.cancel()
        directions = None
    resolution = estimate_resolution(np.concatenate([r.x for r in context.train]))
    train0 = training_residuals(context, start.training)
    floors = noise_floors(
        train0, context.dt, resolution, repeated_residuals(context, start.training)
    )
    judging = Judging(
        context.judged,
        context.scenario_of_run,
        [s.reference for s in context.judging_scenarios],
        floors,
    )
    hold0 = judging.residuals(start)
    where = locate(
        joined([train0, hold0]),
        floors.sigma_position_m,
        floors.sigma_current,
        context.screw_angle,
        context.dt,
        settings,
        context.position_label.travel,
    )
    spec = _replay_spec(context, nominal, floors, replay_cache)
    selector = Selector(
        ReplayPool(
            BoundPool(pool, spec),
            nominal,
            calibrated,  # the card's names among the start values: the noise adds none of them
            judging,
            settings.calibration_tolerance,
            cache=JudgingCache.of(spec) if replay_cache else None,
            nominal_directions=directions,
        ),
        {
            h.name: h
            for h in library_for(context.model)
            if settings.hypotheses is None or h.name in settings.hypotheses
        },
        judging,
        settings,
        sum(float(r.t[-1] - r.t[0]) for r in context.train),
        context,
        {
            "position_resolution": resolution,
            "dead_time_steps": nominal.get("dead_time_steps", 0.0),
        },
    )
    if progress:
        # and the calibrated plant's replay on the held-out runs (its model error)
        selector.pool.progress = progress(selector.expected_tasks() + 1, "diagnose")
    selection = selector.run(start)
    final = selection.replays
    plant = calibrated_plant(
        selection,
        noise,
        context.model,
        context.scenario.plant_parameters,
        settings.calibration_tolerance,
        {"measured": context.measured, "holdout": context.holdout or context.split},
    )
    plant = dataclasses.replace(plant, model_error=_model_error(judging, selector.pool, plant))
    hold_final = judging.residuals(final)
    significant = selection.rounds[0].significant
    remaining, remaining_where, verdict = _verdict_stage(
        context, settings, judging, selection, hold_final
    )
    parent_cpu = time.process_time() - cpu_start
    pool_times = selector.pool.times.as_dict()  # the selection's and the model error's replay
    times = {
        **pool_times,
        "diagnosis": {
            "parent_cpu_s": parent_cpu,
            "idle_wall_estimate_s": parent_cpu + pool_times["total"]["idle_wall_s"],
        },
    }
    return Diagnosis(
        context=context,
        settings=settings,
        noise=noise,
        floors=floors,
        where=where,
        selection=selection,
        significant=significant,
        verdict=verdict,
        remaining=remaining,
        remaining_where=remaining_where,
        metrics_before=judging.metrics(start, settings),
        metrics_after=judging.metrics(final, settings),
        held_out_runs=_held_out_runs(judging, context.judging_scenarios, start, final),
        validation=validation_figures(joined([train0, hold0])),
        train_before=train0,
        holdout_before=hold0,
        holdout_after=hold_final,
        calibrated_plant=plant,
        times=times,
    )


def _replay_spec(
    context: DiagnosisContext, nominal: dict[str, float], floors: Floors, cache: bool = True
) -> ReplaySpec:
    """The recipe of the replay workers: scenarios, nominal plant, training data at the floors,
    the training residuals kept (``cache``) or not."""
    training = TrainingData(
        [r.t for r in context.train],
        [r.x for r in context.train],
        [r.record[r.compared] for r in context.train],
        context.train_scenario_of_run,
        floors.sigma_position_m,
        floors.sigma_current,
        context.train_end,
        context.train[0].compared,
        None
        if context.train[0].drive is None
        else [drive_steps(r.experiment_input) for r in context.train],
    )
    return ReplaySpec(
        context.training_scenarios,
        context.judging_scenarios,
        str(context.fmu),
        nominal,
        training,
        context.model,
        context.ranges,
        TRAINING_CACHE_BYTES if cache else 0,
    )


def _verdict_stage(
    context: DiagnosisContext,
    settings: DiagnosisSettings,
    judging: Judging,
    selection: Selection,
    hold_final: Residuals,
) -> tuple[Remaining, Location, str]:
    """Stage 5: what is left of the held-out gap, where, and the verdict in words."""
    floors = judging.floors
    first = selection.rounds[0]
    metrics = judging.metrics(selection.calibrated, settings)
    left_significant = judging.significant(selection.floor.left, metrics, settings)
    by_metrics_only = left_significant and not judging.significant(
        selection.floor.left, [], settings
    )
    where = locate(
        hold_final,
        floors.sigma_position_m,
        floors.sigma_current,
        context.screw_angle,
        context.dt,
        settings,
        context.position_label.travel,
    )
    remaining = remaining_of(
        first.calibration,
        first.significant,
        selection.floor,
        left_significant and first.significant,
        where,
        (first.position_rms_um, first.current_rms),
        (hold_final.position_rms_um(), hold_final.current_rms()),
        (floors.sigma_position_m, floors.sigma_current),
        context.compared,
        context.position_label,
        by_metrics_only,
    )
    within_calibration = [
        c.name
        for c in (first.candidates if not first.accepted else [])
        if c.judgement.reduction >= EXPLAINS_SHARE
        and c.judgement.consistent
        and {"tolerance", "replayed correction"} & set(c.judgement.failed)
    ]
    groups = selection.accepted
    return remaining, where, verdict_text(first.significant, groups, within_calibration, remaining)


def _held_out_runs(
    judging: Judging, scenarios: list[Scenario], before: Replays, after: Replays
) -> list[HeldOutRun]:
    """Per held-out run: RMS gaps and the benchmark's relative errors, before and after."""
    result = []
    for run, k in zip(judging.runs, judging.scenario_of_run, strict=True):
        grid = judging.grids[k]
        res_before = residuals_of([run], [before.judging[k]], [grid])
        res_after = residuals_of([run], [after.judging[k]], [grid])
        scenario = scenarios[k]
        signal = next(
            (s for s in (scenario.command_disturbance, scenario.disturbance) if s is not None),
            None,
        )
        pulses = (
            (None, None)
            if signal is None
            else tuple(
                pulse_response(run, replays.judging[k], signal, grid) for replays in (before, after)
            )
        )
        result.append(
            HeldOutRun(
                run.source,
                res_before.position_rms_um(),
                res_after.position_rms_um(),
                res_before.current_rms(),
                res_after.current_rms(),
                relative_errors(run, before.judging[k]),
                relative_errors(run, after.judging[k]),
                *pulses,
            )
        )
    return result


def calibrated_plant(
    selection: Selection,
    noise: NoiseModel,
    model: str,
    nominal: dict[str, float],
    tolerance: float,
    made: dict[str, Any],
) -> PlantParameters:
    """The calibrated plant of a diagnosis: noise, accepted effects and calibration correction,
    each value with where it came from.

    Parameters
    ----------
    selection
        The selection: its steps (the rounds that accepted an effect, each with its fit's
        cumulative FMU parameters), its kept effects and their FMU parameters after the joint
        refits, cold refits, swaps and the backward pass (which win), and the last round's
        calibration correction.
    noise
        The noise harmonics kept as plant parameters.
    model
        The plant model the diagnosis ran on.
    nominal
        The diagnosed scenario's plant parameters (SI units of the model's variable table), on
        top of the model's start values: what the correction multiplies.
    tolerance
        The calibration tolerance (relative).
    made
        What made it (``measured``, ``holdout``).

    Notes
    -----
    A value set by an accepted effect's hypothesis is that effect's (``accepted effect NAME
    (step N of twin diagnose)``: the step that accepted it, its fit and held-out figures;
    ``refitted_jointly`` when the final model holds another value); a calibrated parameter
    that no effect sets but the joint refits moved is the joint refit's. A calibrated parameter
    p becomes p (1 + a tol), a the last round's coefficient (|a| <= 1), when that round
    accepted nothing (its residual is what the accepted effects leave); an accepted effect's
    value of p is the one corrected.
    """
    library = {h.name: h for h in plant_model(model).hypotheses}
    parameters: dict[str, float] = {}
    provenance: dict[str, dict[str, Any]] = {}
    for name, value in noise.plant_parameters.items():
        parameters[name] = float(value)
        provenance[name] = {"source": NOISE_SOURCE}
    steps = [r for r in selection.rounds if r.accepted]
    owners: set[str] = set()  # FMU parameters set by an effect of the steps so far
    previous: dict[str, float] = {}
    for number, step in enumerate(steps, start=1):
        best = step.best
        assert best is not None
        cumulative = {k: float(v) for k, v in best.fit.overrides.items()}
        members = list(step.pair.members) if step.pair else step.accepted[:1]
        setting = {name: m for m in members for name in library[m].sets}
        for name in _changed(previous, cumulative):
            if name in setting:
                provenance[name] = _effect_source(setting[name], number, step)
            elif name not in owners and name not in provenance:
                provenance[name] = {"source": JOINT_SOURCE}
        owners |= set(setting)
        parameters |= cumulative
        previous = cumulative
    final = selection.plant_parameters
    for name in set(previous) - set(final):  # the backward pass dropped its effect
        parameters.pop(name, None)
        provenance.pop(name, None)
    swapped_in = {w.candidate.name: w for w in selection.swaps if w.kept}
    for name, value in final.items():
        if name not in provenance:
            effect = next((a.name for a in selection.effects if name in library[a.name].sets), "")
            swap = swapped_in.get(effect)
            provenance[name] = {"source": JOINT_SOURCE} if swap is None else _swap_source(swap)
        elif "effect" in provenance[name] and parameters.get(name) != float(value):
            provenance[name]["refitted_jointly"] = True
        parameters[name] = float(value)
    last = selection.rounds[-1] if selection.rounds else None
    corrections: dict[str, float] = {}
    if last is not None and not last.accepted:
        base = {**plant_model(model).start_values(), **nominal, **parameters}
        for name, a in last.calibration.coefficients.items():
            if a != 0.0:
                corrections[name] = 1.0 + a * tolerance
                parameters[name] = float(base[name] * corrections[name])
                provenance[name] = {
                    "source": CALIBRATION_SOURCE,
                    "before": float(base[name]),
                    "relative_change": float(a * tolerance),
                }
    return PlantParameters(
        model,
        parameters,
        provenance,
        dict(made),
        intervals=_intervals(selection, parameters, corrections, model),
    )


def _model_error(judging: Judging, pool: ReplayPool, plant: PlantParameters) -> ModelError | None:
    """What the calibrated plant, replayed as ``plant.yaml`` writes it (its calibration
    correction applied), still misses on the held-out runs (:mod:`twin_cosim.model_error`);
    None where a held-out run is open-loop (no tracking error of a set of gains to bound)."""
    if any(run.drive is not None for run in judging.runs):
        return None
    replays = pool.tasks("model_error", [SimulateTask(dict(plant.parameters))])[0]
    left = judging.residuals(replays)
    return ModelError.of_discrepancy(left.position, left.current)


def _intervals(
    selection: Selection,
    parameters: dict[str, float],
    corrections: dict[str, float],
    model: str,
) -> dict[str, tuple[float, float]]:
    """The final model's FMU parameters' intervals (:class:`~twin_cosim.gap.which.replay.
    Uncertainty`, drawn around the final model), each moved with its parameter by the
    calibration correction (``corrections``: relative factors), widened to hold the value
    ``parameters`` gives it and kept inside the variable table's range.

    Without the move, a corrected parameter would sit at one end of its interval, and the
    prediction's interval over them would lie almost wholly on one side of the calibrated
    twin's value (on the issue's three-effect machine: 7.57-7.83 um for a twin predicting
    7.58 um and a machine at 7.53 um)."""
    if selection.uncertainty is None:
        return {}
    ranges = plant_model(model).parameters
    intervals = {}
    for name, (low, high) in selection.uncertainty.intervals.items():
        factor = corrections.get(name, 1.0)
        low, high = low * factor, high * factor
        value = parameters.get(name, low)
        variable = ranges[name]
        floor = variable.min if variable.min is not None else -math.inf
        ceiling = variable.max if variable.max is not None else math.inf
        intervals[name] = (max(min(low, value), floor), min(max(high, value), ceiling))
    return intervals


def _changed(before: dict[str, float], after: dict[str, float]) -> list[str]:
    """The names whose value ``after`` holds and ``before`` does not."""
    return [name for name, value in after.items() if before.get(name) != value]


def _effect_source(effect: str, number: int, step: Round) -> dict[str, Any]:
    """Where a value set by an accepted effect came from: the step that accepted it."""
    best = step.best
    assert best is not None
    return jsonable(
        {
            "source": f"accepted effect {effect} (step {number} of twin diagnose)",
            "effect": step.effect,
            "fitted": dict(best.fit.values),
            "holdout_reduction": best.judgement.reduction,
            "holdout_gap_um": [step.position_rms_um, best.judgement.position_rms_um],
        }
    )


def _swap_source(swap: Swap) -> dict[str, Any]:
    """Where a value set by an effect swapped in for an accepted one came from."""
    rival = swap.candidate
    return jsonable(
        {
            "source": f"accepted effect {rival.name} (swapped in for {swap.removed} by twin "
            "diagnose)",
            "effect": rival.name,
            "fitted": dict(rival.fit.values),
            "holdout_reduction": rival.judgement.reduction,
        }
    )
