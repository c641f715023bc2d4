"""The data a diagnosis works on (stage 1): the measured runs checked and split, the plant
model and its library of effects.

- **The plant model**: its variable ranges, its library of hypotheses (:func:`library_for`; a
  model without one is refused before any work) and the hypotheses' context when the data show
  none (:data:`DEFAULT_CONTEXT`); the encoder resolution read off a measured position
  (:func:`estimate_resolution`).
- **Outliers** (:func:`screen_outliers`): a sample of the position or the current is an outlier
  when it departs from the median of its seven neighbours (itself included) by more than
  ``OUTLIER_SPREADS`` robust spreads of all such departures in the run and by more than half the
  signal's robust range (the 0.1 % to 99.9 % quantiles): a glitch of the acquisition
  (``current[1234] = 1e12``), not a breakaway spike, which spans several samples and stays
  within the range. Outliers are replaced by that median and reported; a run with more than the
  allowed share of them is refused.
- **Coverage** (:func:`check_coverage`): the effects of the library show where the drive moves
  and where it turns (friction, inertia and stiffness effects while moving; Stribeck friction,
  backlash and friction asymmetry at a reversal). Training data without them cannot fit those
  effects, and held-out data without them cannot judge them: a time split of a run that only
  dwells in one half, or a held-out run that never turns, would accept or reject effects on
  nothing. Each of the two data sets must hold motion (a stroke of the reference,
  :func:`twin_cosim.gap.data.regimes.strokes`: one direction, more than 1 um) and a reversal
  (two strokes of one run in opposite directions, one after the other, with or without a dwell
  between them), or the diagnosis is refused naming the files and what is missing. An
  open-loop run (a plant driven by its measured signal, turning one way) needs motion only.
- **The split** (:func:`build_context`): each run checked against the reference it follows (its
  own for a scenario whose reference comes from a measured file), outliers repaired; then
  ``--holdout`` runs judge, or every measured run is split in time at ``split``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.ndimage import median_filter

from twin_cosim.gap.data import regimes as regime_model
from twin_cosim.gap.data.residuals import Residuals, residuals_of
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.measured import (
    MeasuredDataError,
    MeasuredRun,
    PositionLabel,
    check_against_reference,
    current_warnings,
    position_label,
)
from twin_cosim.plant import Plant
from twin_cosim.plant_model import Hypothesis, PlantModelError, plant_model
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario, for_measured_run

WINDOW = 7  # samples of the running median of the outlier screen
OUTLIER_SPREADS = 50.0  # robust spreads of the departures from the running median
MAD_TO_SIGMA = 1.4826  # standard deviation / MAD of a normal distribution
MOTION = "motion"
REVERSAL = "reversal"
# Parameters every scenario sets for its own run (twin_cosim.scenario.for_measured_run); the
# replays leave them to the scenario, never override them with the training run's values.
PER_RUN_PARAMETERS = ("load_position_start",)
# Orders of periodic effects when the data show none (the diagnosis takes them from the
# residual's order spectra; twin synth uses them when an effect is given without ``order``).
DEFAULT_CONTEXT: dict[str, float] = {"motor_order": 6.0, "screw_order": 1.0}


class UnknownModelError(ValueError):
    """No hypothesis library for a plant model."""


def library_for(model_identifier: str) -> tuple[Hypothesis, ...]:
    """The hypotheses of a plant model (its FMU's modelIdentifier).

    Raises
    ------
    UnknownModelError
        For a model without a card (the diagnosis cannot guess what another plant's effects
        are called).
    """
    try:
        return plant_model(model_identifier).hypotheses
    except PlantModelError as exc:
        raise UnknownModelError(
            f"no hypothesis library for plant model {model_identifier!r}: {exc} "
            "(each model's library is its models/<model>/card.yaml)"
        ) from exc


def estimate_resolution(x: np.ndarray) -> float:
    """The grid step of a quantised position signal (m), 0.0 when the signal is not on a grid.

    The most common non-zero step between consecutive samples is taken as the resolution when
    every step is (within 1 %) a whole multiple of it.
    """
    steps = np.abs(np.diff(x))
    steps = steps[steps > 1e-15]
    if len(steps) < 10:
        return 0.0
    smallest = np.quantile(steps, 0.01)
    multiples = steps / smallest
    if np.all(np.abs(multiples - np.round(multiples)) < 0.01):
        return float(smallest)
    return 0.0


def _outliers(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the outliers of a signal and the running median that replaces them."""
    median = median_filter(values, size=WINDOW, mode="mirror")
    departure = np.abs(values - median)
    spread = MAD_TO_SIGMA * float(np.median(np.abs(departure - np.median(departure))))
    low, high = np.quantile(values, [0.001, 0.999])
    limit = max(OUTLIER_SPREADS * spread, 0.5 * float(high - low))
    return np.flatnonzero(departure > limit), median


def screen_outliers(run: MeasuredRun, largest_share: float) -> tuple[MeasuredRun, list[str]]:
    """The run with its outliers replaced, and one warning per signal that had any.

    Raises
    ------
    MeasuredDataError
        Naming the file and the column when more than ``largest_share`` of the samples of a
        signal are outliers.
    """
    warnings, replaced = [], {}
    for column in ("x", run.compared):
        values = run.record[column]
        found, median = _outliers(values)
        if len(found) == 0:
            continue
        shown = ", ".join(f"{column}[{i}] = {values[i]:.4g}" for i in found[:5])
        if len(found) > largest_share * len(values):
            raise MeasuredDataError(
                f"{run.source}: column {column!r}: {len(found)} outliers ({shown}, ...), more "
                f"than {100 * largest_share:g} % of the samples: check the acquisition"
            )
        fixed = values.copy()
        fixed[found] = median[found]
        replaced[column] = fixed
        warnings.append(
            f"{run.source}: {len(found)} outlier(s) in column {column!r} replaced by the median "
            f"of their neighbours before fitting: {shown}"
        )
    return (run.with_signals(replaced) if replaced else run), warnings


def missing_regimes(runs: list[MeasuredRun], grids: list[ReferenceGrid]) -> list[str]:
    """What of motion and a reversal none of the runs holds (each against its reference); an
    open-loop run, which turns one way as its drive pushes it, needs motion only."""
    moves = reverses = False
    still = regime_model.RegimeSettings().v_still
    for run, grid in zip(runs, grids, strict=True):
        v_ref = np.interp(run.t, grid.time, grid.velocity)
        direction = np.where(np.abs(v_ref) > still, np.sign(v_ref), 0)
        position = np.interp(run.t, grid.time, grid.position)
        signs = [sign for _, _, sign in regime_model.strokes(direction, position)]
        moves |= bool(signs)
        reverses |= run.drive is not None or any(
            a != b for a, b in zip(signs[:-1], signs[1:], strict=True)
        )
    return [need for need, held in ((MOTION, moves), (REVERSAL, reverses)) if not held]


def check_coverage(
    runs: list[MeasuredRun], grids: list[ReferenceGrid], role: str, how: str
) -> None:
    """Refuse data that miss motion or a reversal.

    Parameters
    ----------
    runs
        The training or the held-out data.
    grids
        The reference each run follows.
    role
        ``"training"`` or ``"held-out"``.
    how
        How the data were chosen, for the message (e.g. ``"time split at t = 6.2 s"``).

    Raises
    ------
    MeasuredDataError
        Naming the files, the span of each, and what is missing.
    """
    missing = missing_regimes(runs, grids)
    if not missing:
        return
    spans = ", ".join(f"{r.source} (t = {r.t[0]:.3g} to {r.t[-1]:.3g} s)" for r in runs)
    raise MeasuredDataError(
        f"{spans}: the {role} data ({how}) hold no {' and no '.join(missing)}; a diagnosis "
        "needs moves and reversals in its training and in its held-out data: record runs "
        "that move and reverse in each part (the whole reference of a scenario that does)"
    )


@dataclass(frozen=True)
class DiagnosisContext:
    """What a diagnosis works on.

    Attributes
    ----------
    scenario : Scenario
        The training scenario.
    fmu : Path
        The plant FMU.
    model : str
        Its model identifier (selects the hypothesis library).
    nominal : dict
        Nominal FMU parameters: start values and the scenario's, less those each run sets for
        itself (:data:`PER_RUN_PARAMETERS`: a held-out run starts where it was measured).
    ranges : dict
        (min, max) of every FMU parameter, from the variable table.
    motor_per_screw : float
        Motor radians per screw radian (the model card's ``motor_per_screw``; 1 without gear).
    dt : float
        Sample period of the measured runs, s.
    measured, holdout : list of str
        The files given.
    train : list of MeasuredRun
        Training data.
    training_scenarios : list of Scenario
        Distinct scenarios the training runs follow (their own reference and disturbance when
        the scenario's reference comes from a measured file).
    train_scenario_of_run : list of int
        Per training run, the index of its scenario.
    judged : list of MeasuredRun
        Held-out data.
    judging_scenarios : list of Scenario
        Distinct scenarios the held-out runs follow.
    scenario_of_run : list of int
        Per held-out run, the index of its scenario.
    train_end : float
        End of the training window (time split), or of the training runs, s.
    split : str
        How the data were split, in words.
    warnings : list of str
        Problems that did not stop the diagnosis.
    repeats : list of list of int
        Groups of training runs (indices into ``train``) that repeat one input
        (:func:`repeat_groups`), two or more each.
    """

    scenario: Scenario
    fmu: Path
    model: str
    nominal: dict[str, float]
    ranges: dict[str, tuple[float, float]]
    motor_per_screw: float
    dt: float
    measured: list[str]
    holdout: list[str]
    train: list[MeasuredRun]
    training_scenarios: list[Scenario]
    train_scenario_of_run: list[int]
    judged: list[MeasuredRun]
    judging_scenarios: list[Scenario]
    scenario_of_run: list[int]
    train_end: float
    split: str
    warnings: list[str]
    repeats: list[list[int]] = field(default_factory=list)

    @property
    def compared(self) -> str:
        """The signal compared beside the position (``current``, or ``motor_speed`` of
        open-loop runs): the name the residuals' ``current`` field holds."""
        return self.train[0].compared

    @property
    def position_label(self) -> PositionLabel:
        """How the reports name and show the compared position: a carriage position, or the
        rotor's angle of open-loop runs."""
        return position_label(self.compared, self.scenario.settings.travel_per_rad)

    def screw_angle(self, motor_angle: np.ndarray) -> np.ndarray:
        """The screw angle (rad) of motor angles (rad)."""
        return motor_angle / self.motor_per_screw


def variable_ranges(plant: Plant) -> dict[str, tuple[float, float]]:
    """(min, max) of every real variable of the FMU (unbounded sides as infinities)."""
    ranges = {}
    for variable in plant.description.modelVariables:
        low = float(variable.min) if variable.min is not None else -np.inf
        high = float(variable.max) if variable.max is not None else np.inf
        ranges[variable.name] = (low, high)
    return ranges


def _checked(runs: list[MeasuredRun], scenarios: list[Scenario], settings, limit) -> tuple:
    """Runs checked against their reference (an open-loop run as its scenario compares it),
    outliers repaired; and the warnings."""
    checked, warnings = [], []
    for run, applies in zip(runs, scenarios, strict=True):
        run = applies.measured_run(run)
        check_against_reference(run, applies.reference)
        run, found = screen_outliers(run, settings.outlier_share)
        checked.append(run)
        commands = current_warnings(run, limit) if run.drive is None else []
        warnings += run.warnings + found + commands
    return checked, warnings


def _distinct(scenarios: list[Scenario]) -> tuple[list[Scenario], list[int]]:
    """The distinct scenarios of a list (by identity) and each item's index among them."""
    distinct: list[Scenario] = []
    index_of = []
    for applies in scenarios:
        index = next((i for i, s in enumerate(distinct) if s is applies), None)
        if index is None:
            distinct.append(applies)
            index = len(distinct) - 1
        index_of.append(index)
    return distinct, index_of


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Two optional signals are the same: both absent, or equal sample by sample."""
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and bool(np.array_equal(a, b))


def same_input(a: Scenario, b: Scenario, run_a: MeasuredRun, run_b: MeasuredRun) -> bool:
    """Whether two runs, each with the scenario it follows, repeat one input: the same
    reference (an open-loop run: the same commanded input,
    :attr:`~twin_cosim.measured.MeasuredRun.experiment_input`, which a measured drive signal
    repeats only up to its noise; its reference is its own measured motion) and the same
    disturbances."""
    if a is b:
        return True
    inputs = _same(a.disturbance, b.disturbance) and _same(
        a.command_disturbance, b.command_disturbance
    )
    if run_a.drive is not None or run_b.drive is not None:
        return inputs and _same(run_a.experiment_input, run_b.experiment_input)
    return inputs and _same(a.reference.position, b.reference.position)


def repeat_groups(
    runs: list[MeasuredRun], scenarios: list[Scenario], scenario_of_run: list[int]
) -> list[list[int]]:
    """Groups of two or more runs (indices) that repeat one input on the same time grid: the
    machine's repeatability, which the twin (replaying each alike) cannot explain."""
    groups: list[list[int]] = []
    for i, run in enumerate(runs):
        scenario = scenarios[scenario_of_run[i]]
        for group in groups:
            first = group[0]
            if len(runs[first].t) == len(run.t) and same_input(
                scenarios[scenario_of_run[first]], scenario, runs[first], run
            ):
                group.append(i)
                break
        else:
            groups.append([i])
    return [g for g in groups if len(g) >= 2]


def build_context(
    scenario: Scenario,
    measured: list[MeasuredRun],
    holdout: list[MeasuredRun],
    fmu: str | None,
    settings: DiagnosisSettings,
) -> DiagnosisContext:
    """Stage 1: the runs checked and split, the plant model and its ranges."""
    with Plant(scenario.plant_fmu(fmu)) as plant:
        fmu_path = plant.fmu_path
        model = plant.description.coSimulation.modelIdentifier
        library_for(model)  # an unknown model is refused here, before any work
        nominal = {
            k: v
            for k, v in {**plant.start_values(), **scenario.plant_parameters}.items()
            if k not in PER_RUN_PARAMETERS
        }
        ranges = variable_ranges(plant)
    following = [for_measured_run(scenario, run) for run in measured]
    judging_of_holdout = [for_measured_run(scenario, run) for run in holdout]
    limit = scenario.settings.current_limit
    train_runs, warnings = _checked(measured, following, settings, limit)
    held_runs, held_warnings = _checked(holdout, judging_of_holdout, settings, limit)
    warnings += held_warnings
    training, train_scenario_of_run = _distinct(following)
    if held_runs:
        judging, scenario_of_run = _distinct(judging_of_holdout)
        train, judged = train_runs, held_runs
        train_end = max(float(r.t[-1]) for r in train_runs)
        split = f"held-out runs {', '.join(r.source for r in held_runs)}"
    else:
        starts = [r.t[0] + settings.split * (r.t[-1] - r.t[0]) for r in train_runs]
        train_end = float(min(starts))
        train = [r.select(r.t < train_end) for r in train_runs]
        judged = [r.select(r.t >= train_end) for r in train_runs]
        judging, scenario_of_run = training, train_scenario_of_run
        split = f"time split at t = {train_end:.4g} s"
    check_coverage(train, [training[i].reference for i in train_scenario_of_run], "training", split)
    check_coverage(judged, [judging[i].reference for i in scenario_of_run], "held-out", split)
    return DiagnosisContext(
        scenario,
        fmu_path,
        model,
        nominal,
        ranges,
        float(plant_model(model).motor_per_screw(nominal)),
        measured[0].period,
        [r.source for r in measured],
        [r.source for r in holdout],
        train,
        training,
        train_scenario_of_run,
        judged,
        judging,
        scenario_of_run,
        train_end,
        split,
        warnings,
        repeat_groups(train, training, train_scenario_of_run),
    )


def training_residuals(context: DiagnosisContext, records: list[RunRecord]) -> Residuals:
    """Training residuals, each run against the replay of the scenario it follows."""
    k = context.train_scenario_of_run
    return residuals_of(
        context.train,
        [records[i] for i in k],
        [context.training_scenarios[i].reference for i in k],
    )


def repeated_residuals(
    context: DiagnosisContext, records: list[RunRecord]
) -> list[list[Residuals]]:
    """Per group of repeats (:attr:`DiagnosisContext.repeats`), each run's training residual."""
    found = []
    for group in context.repeats:
        found.append(
            [
                residuals_of(
                    [context.train[i]],
                    [records[context.train_scenario_of_run[i]]],
                    [context.training_scenarios[context.train_scenario_of_run[i]].reference],
                )
                for i in group
            ]
        )
    return found
