"""A scenario resolved once: the typed value that commands, campaigns and their workers use."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_build.build import build_fmu
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.controller_set import ControllerSet
from twin_cosim.measured import MeasuredRun
from twin_cosim.plant_model import model_of
from twin_cosim.reference import ReferenceError, ReferenceGrid, interpolate
from twin_cosim.scenario.reference_section import open_loop_of, run_disturbance
from twin_cosim.schema import ScenarioError


@dataclass(frozen=True)
class ScenarioFile:
    """What names a scenario, of one axis or of a machine: its name, its text and its file.

    Attributes
    ----------
    name : str
        Its name (the default output folder).
    description : str
        Free text.
    source : Path
        The scenario file.
    """

    name: str
    description: str
    source: Path


@dataclass(frozen=True)
class Scenario(ScenarioFile):
    """A loaded, checked scenario (its name, description and file: :class:`ScenarioFile`).

    Attributes
    ----------
    fmu : Path or None
        The FMU file the scenario names (``plant.fmu``); None for a plant ``model``.
    plant_parameters : dict
        FMU parameter values by name (``load_position_start`` defaults to the reference start),
        after the precedence rule of :mod:`twin_cosim.scenario.plant_parameters`.
    tuned : TunedParameters
        The scenario's six tuned parameters (Fine-Tune by default).
    settings : ControllerSettings
        The controller's fixed settings, plant facts included.
    reference : ReferenceGrid
        The reference on the position-loop grid.
    metrics_window : tuple
        (t0, tF) in s for the metrics; tF None means the end of the run.
    optimize : dict
        The raw ``optimize`` section, checked by :mod:`twin_cosim.optimize.config`.
    measured : Path or None
        The measured run the reference was taken from (``reference.measured``); ``twin
        simulate`` compares the replay with it.
    disturbance : numpy.ndarray or None
        Disturbance input (N.m, or N on a linear axis) per position-loop sample.
    diagnose : dict
        The raw ``diagnose`` section, checked by :mod:`twin_cosim.gap.settings`.
    disturbance_spec : dict
        The signal convention of a measured run's disturbance (``reference.disturbance``).
    command_disturbance : numpy.ndarray or None
        Signal added to the controller's output before the plant, per position-loop sample
        (the command's unit: A, or V for EMPS).
    disturbance_in_record : bool
        The measured command includes ``command_disturbance`` (the twin's recorded command then
        does too).
    model : str or None
        The plant model (folder of models/) the scenario was made for; None for an FMU file.
    plant_parameters_file : Path or None
        The last plant parameter file applied (``plant.parameters_file`` or the command line's).
    measured_columns : dict
        The measured files' column names per signal (``measured_columns``; none: the signals'
        own names).
    drive : str or None
        Open loop: the signal of each measured run that drives the plant (``reference.drive``);
        None: the cascade closes the loop.
    open_loop : numpy.ndarray or None
        Open loop: the plant's current command per position-loop sample, A.
    """

    fmu: Path | None
    plant_parameters: dict[str, float]
    tuned: TunedParameters
    settings: ControllerSettings
    reference: ReferenceGrid
    metrics_window: tuple[float, float | None]
    optimize: dict[str, Any] = field(default_factory=dict)
    measured: Path | None = None
    disturbance: np.ndarray | None = None
    diagnose: dict[str, Any] = field(default_factory=dict)
    disturbance_spec: dict[str, Any] = field(default_factory=dict)
    command_disturbance: np.ndarray | None = None
    disturbance_in_record: bool = False
    model: str | None = None
    plant_parameters_file: Path | None = None
    measured_columns: dict[str, str] = field(default_factory=dict)
    drive: str | None = None
    open_loop: np.ndarray | None = None

    def measured_run(self, run: MeasuredRun) -> MeasuredRun:
        """A measured run as this scenario compares it: an open-loop run driven by its drive
        signal, its position in m (:meth:`~twin_cosim.measured.MeasuredRun.open_loop`); a run
        in closed loop as it is.

        Raises
        ------
        MeasuredDataError
            When an open-loop run lacks its drive signal, a position or the motor speed.
        """
        if self.drive is None:
            return run
        return run.open_loop(self.drive, self.settings.travel_per_rad)

    def plant_fmu(self, override: Path | str | None = None) -> Path:
        """The FMU to run: ``override`` (``--plant``), else the scenario's FMU file, else its
        model's FMU, built from ``models/<model>`` (saying so on stderr) when not built yet."""
        if override is not None:
            return Path(override)
        if self.fmu is not None:
            return self.fmu
        return build_fmu(self.model, announce=True)

    def model_name(self, override: Path | str | None = None) -> str:
        """The plant model that runs: that of ``override`` (an FMU file) when given, else the
        scenario's model, else its FMU file's model identifier."""
        if override is not None or self.model is None:
            return model_of(override if override is not None else self.fmu)
        return self.model


def with_controller_set(scenario: Scenario, controller_set: ControllerSet) -> Scenario:
    """The scenario run by another controller set (its six and its setting overrides).

    Raises
    ------
    ScenarioError
        When the overrides do not make valid settings (e.g. a filter above the Nyquist
        frequency of the scenario's speed loop).
    """
    try:
        settings = controller_set.settings_for(scenario.settings)
    except ValueError as exc:
        raise ScenarioError(f"{scenario.source}: with the controller set: {exc}") from exc
    return dataclasses.replace(scenario, tuned=controller_set.tuned, settings=settings)


def for_measured_run(scenario: Scenario, run: MeasuredRun) -> Scenario:
    """The scenario as it applies to another measured run.

    A scenario whose reference comes from a measured file (``reference.measured``) applies to
    another run of the same machine with that run's reference, start position and disturbance
    (e.g. the EMPS validation run with its force pulses), in open loop with its drive signal
    (and its measured motion as the reference); any other scenario is returned as it is.

    Raises
    ------
    ScenarioError, MeasuredDataError
        When the run does not start at 0 s, its period does not fit the loop's, or an
        open-loop run lacks its drive signal.
    """
    if scenario.measured is None or Path(run.source).resolve() == scenario.measured.resolve():
        return scenario
    if abs(run.t[0]) > 0.5 * run.period:
        raise ScenarioError(f"{run.source}: time must start at 0 s to follow its own reference")
    settings = scenario.settings
    command = None
    try:
        if scenario.drive is None:
            grid = interpolate(run.x_ref, run.period, settings.position_period)
        else:
            run, grid, command = open_loop_of(
                run,
                scenario.drive,
                settings.travel_per_rad,
                settings.torque_constant,
                settings.position_period,
            )
    except ReferenceError as exc:
        raise ScenarioError(f"{run.source}: reference: {exc}") from exc
    at_input, at_command = run_disturbance(run, scenario.disturbance_spec, grid)
    return dataclasses.replace(
        scenario,
        reference=grid,
        plant_parameters={**scenario.plant_parameters, "load_position_start": float(run.x[0])},
        measured=Path(run.source),
        disturbance=at_input,
        command_disturbance=at_command,
        open_loop=command,
    )
