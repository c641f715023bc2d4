"""The diagnosis: where the gap lies, which unmodelled effect causes it, how far it shrinks.

1. Replay the scenario on the twin; residuals r_x = x_meas - x_sim (m), r_i = i_meas - i_sim (A).
2. Noise model: the main harmonics of the measured position at standstill (the paper's Fourier
   series) become plant parameters of every later replay; the noise floors sigma_x, sigma_i are
   the robust spread of the residuals at standstill.
3. Where: per motion regime the share of residual energy and its enrichment; order spectra
   against motor and screw angle and a spectrum in Hz, with the position-periodic / temporal
   rule; the paper's validation figures (max, mean absolute and RMS position gap).
4. Which: every hypothesis of :mod:`twin_cosim.gap.effects` fitted on the training data,
   ranked by BIC on the training residual; accepted only on held-out data (see Thresholds).
   Greedy forward selection adds effects one at a time, each fitted on top of those accepted;
   later rounds refit the ``later_round_candidates`` (6) best-ranked remaining hypotheses.
5. How far: for each accepted effect the held-out gap before and after, per regime.

Split: with ``--holdout`` files the measured runs train and the holdout runs judge (for a
scenario whose reference comes from a measured file, the held-out runs follow their own
reference and disturbance, e.g. the EMPS validation run with its pulses); otherwise
every measured run is split in time at ``split`` (default the midpoint): samples before train,
samples after judge. The fit never sees a held-out sample.

Thresholds (``DiagnosisSettings``):
- the held-out gap is *significant* when the largest relative error of the twin's E_pk, ITAE and
  IAU against the measured ones is at least ``significance_metric`` (2 %): a gap a servo engineer
  would see in the figures of merit, above what a few percent of calibration error gives;
- an effect is *accepted* when the gap is significant, the effect cuts the normalised
  held-out RMS by at least ``accept_reduction`` (25 %), it explains more than the *calibration
  floor* (the normalised held-out RMS that moving each calibrated parameter of
  :data:`~twin_cosim.gap.effects.CALIBRATED` by +/- ``calibration_tolerance``, 3 %, can explain,
  added in quadrature), a change of a calibrated parameter itself (Coulomb level, backlash,
  inertia, stiffness) exceeds that tolerance, and it is *consistent*: it makes neither the
  position nor the current held-out RMS worse than ``worsen_limit`` (1.1) times what it was,
  plus the noise floor (a wrong effect can trade one signal for the other: a motor-order ripple
  fitted to a lead error cuts the position gap and multiplies the current gap). Effects that
  pass all but the calibration tests are declared not diagnosable beyond calibration error;
- two effects form a *group* when both pass, their reductions differ by less than 0.1 and the
  changes they predict on the held-out data correlate at 0.9 or more.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from twin_cosim.cosim import run_scenario
from twin_cosim.gap import noise as noise_model
from twin_cosim.gap import regimes as regime_model
from twin_cosim.gap import spectra
from twin_cosim.gap.effects import CALIBRATED, estimate_resolution, library_for
from twin_cosim.gap.replay import FitResult, FitTask, ReplaySpec, SimulateTask, TrainingData
from twin_cosim.measured import (
    MeasuredRun,
    check_against_reference,
    current_warnings,
)
from twin_cosim.metrics import UM_PER_M
from twin_cosim.plant import Plant
from twin_cosim.scenario import Scenario, for_measured_run
from twin_cosim.workers import make_pool

EFFECTIVE_SAMPLE_SPACING_S = 0.01  # residuals are correlated: one independent sample per 10 ms
GEAR_RATIO_DEFAULT = 1.5


@dataclass(frozen=True)
class DiagnosisSettings:
    """Split, thresholds and effort of a diagnosis (see the module docstring)."""

    split: float = 0.5
    significance_metric: float = 0.02
    accept_reduction: float = 0.25
    calibration_tolerance: float = 0.03
    worsen_limit: float = 1.1
    group_reduction_margin: float = 0.1
    group_correlation: float = 0.9
    max_effects: int = 3
    later_round_candidates: int = 6
    hypotheses: tuple[str, ...] | None = None  # None: the whole library of the plant model
    significance_rms: float | None = None  # also significant when the normalised RMS reaches it


def settings_from(scenario: Scenario, split: float | None = None) -> DiagnosisSettings:
    """Settings from the scenario's ``diagnose`` section (any field of DiagnosisSettings but
    ``hypotheses`` may be given); ``split`` overrides the section's.

    Raises
    ------
    ValueError
        Naming the file and the key on an unknown key or a value that is not a number.
    """
    allowed = {f for f in DiagnosisSettings.__dataclass_fields__ if f != "hypotheses"}
    section = dict(scenario.diagnose)
    unknown = sorted(set(section) - allowed)
    if unknown:
        raise ValueError(
            f"{scenario.source}: diagnose: unknown key(s) {unknown}; allowed: {sorted(allowed)}"
        )
    for key, value in section.items():
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise ValueError(
                f"{scenario.source}: diagnose.{key}: expected a finite number, got {value!r}"
            )
    if split is not None:
        section["split"] = split
    return DiagnosisSettings(**section)


@dataclass
class Windowed:
    """Measured runs cut into the training part and the held-out part."""

    train: list[MeasuredRun]
    holdout: list[MeasuredRun]
    train_end: float


def split_runs(measured: list[MeasuredRun], holdout: list[MeasuredRun], split: float) -> Windowed:
    """Training and held-out runs: the holdout files, or a time split of each measured run."""
    if holdout:
        end = max(run.t[-1] for run in measured)
        return Windowed(measured, holdout, end)
    if not 0.1 <= split <= 0.9:
        raise ValueError(f"split must lie in [0.1, 0.9], got {split}")
    starts = [run.t[0] + split * (run.t[-1] - run.t[0]) for run in measured]
    t_split = min(starts)
    train = [run.select(run.t < t_split) for run in measured]
    held = [run.select(run.t >= t_split) for run in measured]
    return Windowed(train, held, t_split)


def _sim_at(record: pd.DataFrame, column: str, t: np.ndarray) -> np.ndarray:
    return np.interp(t, record["t"].to_numpy(), record[column].to_numpy())


@dataclass
class Residuals:
    """Residuals of a set of runs against one replay, concatenated over the runs."""

    t: np.ndarray
    position: np.ndarray  # m
    current: np.ndarray  # A
    regimes: np.ndarray  # codes of twin_cosim.gap.regimes.REGIMES
    motor_angle: np.ndarray  # rad, of the replay

    def normalised_rms(self, sigma_x: float, sigma_i: float) -> float:
        """sqrt(mean of (r_x/sigma_x)^2 and (r_i/sigma_i)^2)."""
        return math.sqrt(
            0.5 * (np.mean((self.position / sigma_x) ** 2) + np.mean((self.current / sigma_i) ** 2))
        )


def _joined(first: Residuals, second: Residuals | None) -> Residuals:
    """Two residual sets as one (their samples one after the other)."""
    if second is None:
        return first
    return Residuals(
        *(
            np.concatenate([getattr(first, f), getattr(second, f)])
            for f in ("t", "position", "current", "regimes", "motor_angle")
        )
    )


def residuals(runs: list[MeasuredRun], record: pd.DataFrame, scenario: Scenario) -> Residuals:
    """Residuals of ``runs`` against the replay ``record``, with the regime of every sample."""
    grid = scenario.reference
    parts = []
    for run in runs:
        v_ref = np.interp(run.t, grid.time, grid.velocity)
        a_ref = np.interp(run.t, grid.time, grid.acceleration)
        labels = regime_model.classify_regimes(run.t, v_ref, a_ref)
        parts.append(
            (
                run.t,
                run.x - _sim_at(record, "x", run.t),
                run.current - _sim_at(record, "current", run.t),
                labels,
                _sim_at(record, "motor_angle", run.t),
            )
        )
    return Residuals(*(np.concatenate(column) for column in zip(*parts, strict=True)))


def _errors_of(t: np.ndarray, error: np.ndarray, current: np.ndarray) -> dict[str, float]:
    """E_pk (um), ITAE (um.s^2) and IAU (A.s) of one window, as in twin_cosim.metrics."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    e = np.abs(error) * UM_PER_M
    return {
        "E_pk_um": float(e.max()),
        "ITAE": float(np.sum((t - t[0]) * e) * dt),
        "IAU": float(np.sum(np.abs(current)) * dt),
    }


def metric_errors(runs: list[MeasuredRun], record: pd.DataFrame) -> dict[str, Any]:
    """Relative errors of the twin's E_pk, ITAE and IAU against the measured ones (first run)."""
    run = runs[0]
    measured = _errors_of(run.t, run.x_ref - run.x, run.current)
    simulated = _errors_of(
        run.t, run.x_ref - _sim_at(record, "x", run.t), _sim_at(record, "current", run.t)
    )
    relative = {
        k: abs(simulated[k] - measured[k]) / abs(measured[k]) if measured[k] else 0.0
        for k in measured
    }
    return {
        "measured": measured,
        "twin": simulated,
        "relative_error": relative,
        "largest_relative_error": max(relative.values()),
    }


def validation_figures(res: Residuals) -> dict[str, float]:
    """The paper's validation figures of the position gap: max, mean absolute, RMS (um)."""
    gap = np.abs(res.position) * UM_PER_M
    return {
        "max_um": float(gap.max()),
        "mean_abs_um": float(gap.mean()),
        "rms_um": float(np.sqrt(np.mean(gap**2))),
    }


def where(res: Residuals, gear_ratio: float, dt: float) -> dict[str, Any]:
    """Regime shares of both residuals, order and Hz analysis of the constant-velocity stretches."""
    code = regime_model.REGIMES.index("constant_velocity")
    stretches = regime_model.segments(res.regimes, code)
    speed_groups = _speed_groups(res, stretches, dt)
    result = {
        "position": regime_model.energy_shares(res.position, res.regimes),
        "current": regime_model.energy_shares(res.current, res.regimes),
        "periodicity": {},
    }
    for signal, residual in (("position", res.position), ("current", res.current)):
        for angle_name, angle in (
            ("motor", res.motor_angle),
            ("screw", res.motor_angle / gear_ratio),
        ):
            verdict = spectra.periodicity(residual, angle, dt, speed_groups)
            result["periodicity"][f"{signal}_vs_{angle_name}_angle"] = _jsonable(verdict)
    return result


def _speed_groups(
    res: Residuals, stretches: list[tuple[int, int]], dt: float
) -> list[list[tuple[int, int]]]:
    """Constant-velocity stretches grouped by speed level (within 10 %)."""
    levels: list[tuple[float, list[tuple[int, int]]]] = []
    for start, stop in stretches:
        angle = res.motor_angle[start:stop]
        if stop - start < 2:
            continue
        speed = abs(angle[-1] - angle[0]) / ((stop - start - 1) * dt)
        for level, members in levels:
            if abs(speed - level) <= 0.1 * level:
                members.append((start, stop))
                break
        else:
            levels.append((speed, [(start, stop)]))
    return [members for _, members in levels]


def _jsonable(value: Any) -> Any:
    if hasattr(value, "__dataclass_fields__"):
        return _jsonable(asdict(value))
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def _dominant_order(res: Residuals, signal: np.ndarray, angle: np.ndarray, default: float) -> float:
    code = regime_model.REGIMES.index("constant_velocity")
    stretches = regime_model.segments(res.regimes, code)
    orders, amplitude = spectra.order_spectrum(signal, angle, stretches)
    if len(orders) == 0:
        return default
    peak = spectra.dominant_peak(orders, amplitude)
    return float(max(1, round(peak.location))) if peak else default


@dataclass
class Candidate:
    """A fitted hypothesis judged on the held-out data."""

    fit: FitResult
    n_parameters: int
    above_calibration_floor: bool = True
    consistent: bool = True
    calibration_floor: float = 0.0  # normalised RMS that calibration errors alone can explain
    explained: float = 0.0  # normalised RMS of what the effect removes
    bic: float = 0.0
    holdout_rms: float = 0.0
    reduction: float = 0.0
    position_rms_um: float = 0.0
    current_rms_A: float = 0.0
    change: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _bic(cost: float, n_parameters: int, train_seconds: float) -> float:
    n_eff = max(train_seconds / EFFECTIVE_SAMPLE_SPACING_S, 1.0)
    return n_eff * math.log(max(cost, 1e-300)) + n_parameters * math.log(n_eff)


@dataclass
class Diagnosis:
    """Everything the report shows; ``summary`` is the JSON the CLI prints."""

    summary: dict[str, Any]
    nominal_record: pd.DataFrame
    final_record: pd.DataFrame
    train_before: Residuals
    holdout_before: Residuals
    holdout_after: Residuals
    train_end: float


def diagnose(
    scenario: Scenario,
    measured: list[MeasuredRun],
    holdout: list[MeasuredRun] | None = None,
    fmu: str | None = None,
    settings: DiagnosisSettings = DiagnosisSettings(),
    workers: int | None = None,
) -> Diagnosis:
    """Diagnose the gap between the measured runs and the twin's replay of the scenario."""
    holdout = holdout or []
    warnings: list[str] = []
    held_scenario = for_measured_run(scenario, holdout[0]) if holdout else scenario
    for runs, applies in ((measured, scenario), (holdout, held_scenario)):
        for run in runs:
            check_against_reference(run, applies.reference)
            warnings += run.warnings + current_warnings(run, scenario.settings.current_limit)
    windows = split_runs(measured, holdout, settings.split)
    fmu_path = Path(fmu) if fmu else scenario.fmu
    with Plant(fmu_path) as plant:
        model = plant.description.coSimulation.modelIdentifier
        nominal = {**plant.start_values(), **scenario.plant_parameters}
        gear_ratio = nominal.get("gear_ratio", GEAR_RATIO_DEFAULT)
        first = run_scenario(plant, scenario, plant_overrides=nominal)
        raw = residuals(windows.train, first, scenario)
        still = raw.regimes == regime_model.REGIMES.index("standstill")
        harmonics = noise_model.noise_harmonics(raw.t, raw.position, still)
        noise_parameters = noise_model.as_plant_parameters(harmonics) if harmonics else {}
        nominal |= noise_parameters
        record = run_scenario(plant, scenario, plant_overrides=nominal) if harmonics else first
        held_record = (
            record
            if held_scenario is scenario
            else run_scenario(plant, held_scenario, plant_overrides=nominal)
        )
    train0 = residuals(windows.train, record, scenario)
    hold0 = residuals(windows.holdout, held_record, held_scenario)
    still = train0.regimes == regime_model.REGIMES.index("standstill")
    sigma_x = max(noise_model.noise_floor(train0.position, still), 1e-9)
    sigma_i = max(noise_model.noise_floor(train0.current, still), 1e-4)
    if not still.any():
        warnings.append("no standstill in the training data: noise floors set to 1 nm and 0.1 mA")
    dt = measured[0].period
    all0 = _joined(
        residuals(measured, record, scenario),
        residuals(holdout, held_record, held_scenario) if holdout else None,
    )
    located = where(all0, gear_ratio, dt)
    context = {
        "motor_order": _dominant_order(train0, train0.current, train0.motor_angle, 6.0),
        "screw_order": _dominant_order(
            train0, train0.current, train0.motor_angle / gear_ratio, 1.0
        ),
        "position_resolution": estimate_resolution(np.concatenate([r.x for r in windows.train])),
        "dead_time_steps": nominal.get("dead_time_steps", 0.0),
    }
    training = TrainingData(
        [r.t for r in windows.train],
        [r.x for r in windows.train],
        [r.current for r in windows.train],
        sigma_x,
        sigma_i,
        windows.train_end,
    )
    spec = ReplaySpec(
        str(scenario.source),
        str(fmu) if fmu else None,
        nominal,
        training,
        model,
        holdout[0].source if held_scenario is not scenario else None,
    )
    train_seconds = sum(float(r.t[-1] - r.t[0]) for r in windows.train)
    pool = make_pool(spec, workers)
    try:
        steps, effects, last_round, base, current_record = _select(
            pool,
            settings,
            context,
            windows,
            held_scenario,
            held_record,
            sigma_x,
            sigma_i,
            train_seconds,
            nominal,
            model,
        )
    finally:
        pool.close()
    hold_final = residuals(windows.holdout, current_record, held_scenario)
    before_rms = hold0.normalised_rms(sigma_x, sigma_i)
    metric_before = metric_errors(windows.holdout, held_record)
    significant = _significant(metric_before, before_rms, settings)
    summary = {
        "scenario": str(scenario.source),
        "measured": [r.source for r in measured],
        "holdout": [r.source for r in holdout] or f"time split at t = {windows.train_end:.4g} s",
        "accepted": [step["effect"] for step in steps],
        "steps": steps,
        "effects": effects,
        "last_round": last_round,
        "where": {"position": located["position"], "current": located["current"]},
        "periodicity": located["periodicity"],
        "gap": {
            "significant": bool(significant),
            "holdout_normalised_rms": before_rms,
            "verdict": _verdict(significant, steps, effects, settings),
            "validation_figures": validation_figures(all0),
            "holdout_metrics_before": metric_before,
            "holdout_metrics_after": metric_errors(windows.holdout, current_record),
            "unexplained_share_by_regime": _unexplained(hold0, hold_final),
        },
        "noise": {
            "harmonics": _jsonable(harmonics),
            "plant_parameters": noise_parameters,
            "sigma_position_um": sigma_x * UM_PER_M,
            "sigma_current_A": sigma_i,
        },
        "context": context,
        "thresholds": _jsonable(asdict(settings)),
        "warnings": warnings,
        "final_plant_parameters": base,
    }
    return Diagnosis(
        _jsonable(summary), record, current_record, train0, hold0, hold_final, windows.train_end
    )


def _verdict(
    significant: bool,
    steps: list[dict[str, Any]],
    effects: list[dict[str, Any]],
    settings: DiagnosisSettings,
) -> str:
    if not significant:
        return (
            "no significant gap: the twin's E_pk, ITAE and IAU match the measured ones within "
            "the significance threshold"
        )
    if not steps:
        floor = [
            r["name"]
            for r in effects
            if not r["above_calibration_floor"]
            and r["holdout_reduction"] >= settings.accept_reduction
        ]
        if floor:
            return (
                f"significant gap, but the effects that explain it ({', '.join(floor)}) are "
                "smaller than the calibration tolerance: not diagnosable beyond calibration error"
            )
        return (
            "significant gap that no effect of the library explains on held-out data: "
            "see 'where' for its location"
        )
    return "gap explained in part or whole by: " + ", ".join(
        "{" + ", ".join(s["effect"]) + "}" if isinstance(s["effect"], list) else s["effect"]
        for s in steps
    )


def _unexplained(before: Residuals, after: Residuals) -> dict[str, float]:
    """Held-out position residual energy left per regime, as a share of what it was."""
    shares = {}
    for code, name in enumerate(regime_model.REGIMES):
        mask = before.regimes == code
        energy = float(np.sum(before.position[mask] ** 2))
        if mask.any() and energy > 0:
            shares[name] = float(np.sum(after.position[mask] ** 2)) / energy
    return shares


def _significant(
    metrics: dict[str, Any], normalised_rms: float, settings: DiagnosisSettings
) -> bool:
    """The held-out gap test of the module docstring."""
    if metrics["largest_relative_error"] >= settings.significance_metric:
        return True
    return settings.significance_rms is not None and normalised_rms >= settings.significance_rms


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2)))


def _judge(
    candidate: Candidate,
    hold: Residuals,
    base_rms: float,
    record: pd.DataFrame,
    runs: list[MeasuredRun],
    scenario: Scenario,
    sigma_x: float,
    sigma_i: float,
    settings: DiagnosisSettings,
) -> None:
    """Held-out figures of a fitted candidate whose replay is ``record``."""
    after = residuals(runs, record, scenario)
    candidate.holdout_rms = after.normalised_rms(sigma_x, sigma_i)
    candidate.reduction = 1.0 - candidate.holdout_rms / base_rms if base_rms > 0 else 0.0
    candidate.explained = math.sqrt(max(base_rms**2 - candidate.holdout_rms**2, 0.0))
    candidate.position_rms_um = float(np.sqrt(np.mean(after.position**2))) * UM_PER_M
    candidate.current_rms_A = float(np.sqrt(np.mean(after.current**2)))
    worse_x = candidate.position_rms_um / UM_PER_M - settings.worsen_limit * _rms(hold.position)
    worse_i = candidate.current_rms_A - settings.worsen_limit * _rms(hold.current)
    candidate.consistent = worse_x <= sigma_x and worse_i <= sigma_i
    x_change = (hold.position - after.position) / sigma_x  # = x_sim_after - x_sim_before
    i_change = (hold.current - after.current) / sigma_i
    candidate.change = np.concatenate([x_change, i_change])


def _select(
    pool,
    settings: DiagnosisSettings,
    context: dict[str, float],
    windows: Windowed,
    scenario: Scenario,
    record: pd.DataFrame,
    sigma_x: float,
    sigma_i: float,
    train_seconds: float,
    nominal: dict[str, float],
    model: str,
):
    """Greedy forward selection.

    Returns the accepted steps, the first and the last round's tables, the FMU parameters of the
    accepted effects and the replay with them.
    """
    base: dict[str, float] = {}
    library = {h.name: h for h in library_for(model)}
    remaining = list(settings.hypotheses or library)
    steps: list[dict[str, Any]] = []
    first_round: list[dict[str, Any]] = []
    last_round: list[dict[str, Any]] = []
    current = record
    while remaining and len(steps) < settings.max_effects:
        hold = residuals(windows.holdout, current, scenario)
        base_rms = hold.normalised_rms(sigma_x, sigma_i)
        metrics = metric_errors(windows.holdout, current)
        if not _significant(metrics, base_rms, settings):
            break
        floor = _calibration_floor(
            pool, hold, current, windows, scenario, nominal, base, model, settings, sigma_x, sigma_i
        )
        fits = dict(pool.imap([FitTask(name, base, context) for name in remaining]))
        fitted = [fits[i] for i in range(len(remaining))]
        records = dict(pool.imap([SimulateTask(f.overrides) for f in fitted]))
        candidates = []
        for i, fit in enumerate(fitted):
            hypothesis = library[fit.hypothesis]
            candidate = Candidate(fit, len(hypothesis.parameters), calibration_floor=floor)
            if hypothesis.relative_size is not None and fit.values:
                values = np.array(list(fit.values.values()))
                size = hypothesis.relative_size(values, {**nominal, **base})
                candidate.above_calibration_floor = size >= settings.calibration_tolerance
            candidate.bic = _bic(fit.train_cost, candidate.n_parameters, train_seconds)
            _judge(
                candidate,
                hold,
                base_rms,
                records[i],
                windows.holdout,
                scenario,
                sigma_x,
                sigma_i,
                settings,
            )
            candidates.append((candidate, records[i]))
        candidates.sort(key=lambda pair: pair[0].bic)
        before_um = float(np.sqrt(np.mean(hold.position**2))) * UM_PER_M
        before_A = float(np.sqrt(np.mean(hold.current**2)))
        table = [_row(c, before_um, before_A, settings) for c, _ in candidates]
        if not steps:
            first_round = table
        last_round.clear()
        last_round.extend(table)
        passing = [(c, r) for c, r in candidates if _passes(c, settings)]
        if not passing:
            break
        best, best_record = passing[0]
        group = [best.fit.hypothesis] + [
            c.fit.hypothesis
            for c, _ in passing[1:]
            if abs(c.reduction - best.reduction) < settings.group_reduction_margin
            and _correlation(c.change, best.change) >= settings.group_correlation
        ]
        base = dict(best.fit.overrides)
        current = best_record
        steps.append(
            {
                "effect": group if len(group) > 1 else group[0],
                "fitted": best.fit.hypothesis,
                "params": best.fit.values,
                "plant_parameters": best.fit.overrides,
                "holdout_gap_before_um": before_um,
                "holdout_gap_after_um": best.position_rms_um,
                "holdout_current_before_A": before_A,
                "holdout_current_after_A": best.current_rms_A,
                "holdout_normalised_rms_before": base_rms,
                "holdout_normalised_rms_after": best.holdout_rms,
                "reduction": best.reduction,
                "ranking": table,
            }
        )
        ranked = [row["name"] for row in first_round]
        remaining = [name for name in ranked if name not in group and name in remaining]
        remaining = remaining[: settings.later_round_candidates]
    return steps, first_round, last_round, base, current


def _row(
    candidate: Candidate, before_um: float, before_A: float, settings: DiagnosisSettings
) -> dict[str, Any]:
    fit = candidate.fit
    return {
        "name": fit.hypothesis,
        "params": fit.values,
        "train_cost": fit.train_cost,
        "bic": candidate.bic,
        "replays": fit.replays,
        "holdout_gap_before_um": before_um,
        "holdout_gap_after_um": candidate.position_rms_um,
        "holdout_current_before_A": before_A,
        "holdout_current_after_A": candidate.current_rms_A,
        "holdout_reduction": candidate.reduction,
        "above_calibration_floor": (
            candidate.above_calibration_floor and candidate.explained > candidate.calibration_floor
        ),
        "explained_normalised_rms": candidate.explained,
        "calibration_floor_normalised_rms": candidate.calibration_floor,
        "consistent": candidate.consistent,
        "passes": _passes(candidate, settings),
    }


def _passes(candidate: Candidate, settings: DiagnosisSettings) -> bool:
    return (
        candidate.reduction >= settings.accept_reduction
        and candidate.above_calibration_floor
        and candidate.explained > candidate.calibration_floor
        and candidate.consistent
    )


def _calibration_floor(
    pool,
    hold: Residuals,
    record: pd.DataFrame,
    windows: Windowed,
    scenario: Scenario,
    nominal: dict[str, float],
    base: dict[str, float],
    model: str,
    settings: DiagnosisSettings,
    sigma_x: float,
    sigma_i: float,
) -> float:
    """Normalised held-out RMS that calibration errors alone can explain.

    Each calibrated parameter (:data:`twin_cosim.gap.effects.CALIBRATED`) is moved by
    +/- the calibration tolerance; the larger change it makes to the held-out replay counts, and
    the changes add in quadrature. An effect must explain more than this to be accepted.
    """
    names = [n for n in CALIBRATED.get(model, ()) if n in nominal]
    moves = [
        {**base, name: {**nominal, **base}[name] * (1.0 + sign * settings.calibration_tolerance)}
        for name in names
        for sign in (1.0, -1.0)
    ]
    replays = dict(pool.imap([SimulateTask(m) for m in moves]))
    total = 0.0
    for i in range(0, len(moves), 2):
        changes = []
        for replay in (replays[i], replays[i + 1]):
            moved = residuals(windows.holdout, replay, scenario)
            change = Residuals(
                hold.t,
                hold.position - moved.position,
                hold.current - moved.current,
                hold.regimes,
                hold.motor_angle,
            )
            changes.append(change.normalised_rms(sigma_x, sigma_i))
        total += max(changes) ** 2
    return math.sqrt(total)


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) != len(b) or np.std(a) == 0 or np.std(b) == 0:
        return 0.0
    return float(abs(np.corrcoef(a, b)[0, 1]))
