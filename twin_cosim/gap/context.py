"""Stage 1 of a diagnosis: the context it works on.

The scenario, the plant model and its variable ranges, the measured runs checked (each against
the reference it follows: its own for a scenario whose reference comes from a measured file;
outliers repaired and reported, :mod:`twin_cosim.gap.outliers`) and split into training and
held-out data: ``--holdout`` runs judge, or every measured run is split in time at ``split``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twin_cosim.gap.coverage import check_coverage
from twin_cosim.gap.effects import library_for
from twin_cosim.gap.outliers import screen_outliers
from twin_cosim.gap.residuals import Residuals, residuals_of
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.measured import MeasuredRun, check_against_reference, current_warnings
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario, for_measured_run

# Parameters every scenario sets for its own run (twin_cosim.scenario.for_measured_run); the
# replays leave them to the scenario, never override them with the training run's values.
PER_RUN_PARAMETERS = ("load_position_start",)


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
    """Runs checked against their reference, outliers repaired; and the warnings."""
    checked, warnings = [], []
    for run, applies in zip(runs, scenarios, strict=True):
        check_against_reference(run, applies.reference)
        run, found = screen_outliers(run, settings.outlier_share)
        checked.append(run)
        warnings += run.warnings + found + current_warnings(run, limit)
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
    )


def training_residuals(context: DiagnosisContext, records: list[RunRecord]) -> Residuals:
    """Training residuals, each run against the replay of the scenario it follows."""
    k = context.train_scenario_of_run
    return residuals_of(
        context.train,
        [records[i] for i in k],
        [context.training_scenarios[i].reference for i in k],
    )
