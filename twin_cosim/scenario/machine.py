"""A machine of several axes resolved once: the typed value of a scenario with ``axes:``.

Each axis is a plant (model or FMU file, its parameters) with its own controller set and the
limits the interpolator must respect; :meth:`MachineScenario.axis_scenario` gives one axis as an
ordinary single-axis :class:`~twin_cosim.scenario.resolved.Scenario` once its reference is known
(the per-axis diagnosis and campaigns take that).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fmu_build.build import build_fmu
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.plant_model import model_of
from twin_cosim.reference import ReferenceGrid
from twin_cosim.scenario.resolved import Scenario

AXIS_NAMES = ("X", "Y", "Z")


@dataclass(frozen=True)
class AxisLimits:
    """What the interpolator may ask of one axis.

    Attributes
    ----------
    velocity : float
        Largest speed, m/s (also the rapid traverse speed of G00).
    acceleration : float
        Largest acceleration, m/s^2.
    jerk : float
        Largest jerk, m/s^3.
    """

    velocity: float
    acceleration: float
    jerk: float


@dataclass(frozen=True)
class AxisSetup:
    """One axis of a machine.

    Attributes
    ----------
    name : str
        ``X``, ``Y`` or ``Z``.
    model : str or None
        Plant model (folder of models/); None for an FMU file.
    fmu : Path or None
        FMU file of the axis' plant; None for a model.
    plant_parameters : dict
        FMU parameter values by name (SI units), after the precedence rule of
        :mod:`twin_cosim.scenario.plant_section`.
    plant_parameters_file : Path or None
        The axis' ``plant.parameters_file``.
    tuned : TunedParameters
        The axis' six tuned parameters.
    settings : ControllerSettings
        The axis' controller settings, plant facts included.
    limits : AxisLimits
        Velocity, acceleration and jerk limits of the interpolator.
    """

    name: str
    model: str | None
    fmu: Path | None
    plant_parameters: dict[str, float]
    plant_parameters_file: Path | None
    tuned: TunedParameters
    settings: ControllerSettings
    limits: AxisLimits

    def plant_fmu(self) -> Path:
        """The axis' FMU file, its model's built (saying so on stderr) when not built yet."""
        return self.fmu if self.fmu is not None else build_fmu(self.model, announce=True)

    def model_name(self) -> str:
        """The axis' plant model: its model, else its FMU file's model identifier."""
        return self.model if self.model is not None else model_of(self.fmu)


@dataclass(frozen=True)
class MachineScenario:
    """A loaded, checked scenario of several axes.

    Attributes
    ----------
    name : str
        Its name (the default output folder).
    description : str
        Free text.
    source : Path
        The scenario file.
    axes : tuple of AxisSetup
        The axes in the order X, Y, Z.
    sample_period : float
        Interpolation period of the CNC, s (4 ms): the per-axis references are sampled at it.
    program : Path or None
        The scenario's part program (``program:``), None when it names none.
    settle : float
        Standstill after the end of the path, s, that every run keeps recording.
    max_samples : int
        Position-loop samples a run may have at most.
    optimize : dict
        The raw ``optimize`` section (contour tuning).
    diagnose : dict
        The raw ``diagnose`` section (the diagnosis of each axis).
    """

    name: str
    description: str
    source: Path
    axes: tuple[AxisSetup, ...]
    sample_period: float
    program: Path | None = None
    settle: float = 0.2
    max_samples: int = 2_400_000
    optimize: dict[str, Any] = field(default_factory=dict)
    diagnose: dict[str, Any] = field(default_factory=dict)

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The axes' names, in order."""
        return tuple(a.name for a in self.axes)

    def axis(self, name: str) -> AxisSetup:
        """The axis of that name; ValueError names the machine's axes when there is none."""
        for axis in self.axes:
            if axis.name == name:
                return axis
        raise ValueError(f"{self.source}: no axis {name!r}; the axes are {list(self.axis_names)}")

    def with_tuned(self, tuned: dict[str, TunedParameters]) -> MachineScenario:
        """The machine with other tuned parameters on the axes named in ``tuned``."""
        unknown = sorted(set(tuned) - set(self.axis_names))
        if unknown:
            raise ValueError(f"tuned parameters for axes {unknown} the machine does not have")
        axes = tuple(
            dataclasses.replace(a, tuned=tuned[a.name]) if a.name in tuned else a for a in self.axes
        )
        return dataclasses.replace(self, axes=axes)

    def axis_scenario(
        self, name: str, grid: ReferenceGrid, optimize: dict | None = None
    ) -> Scenario:
        """One axis as a single-axis scenario following ``grid`` (its reference).

        The plant starts at the reference's first position; ``optimize`` is the single-axis
        ``optimize`` section to give it (none by default).
        """
        axis = self.axis(name)
        return Scenario(
            name=f"{self.name}-{name}",
            description=f"axis {name} of {self.name}",
            source=self.source,
            fmu=axis.fmu,
            plant_parameters={
                **axis.plant_parameters,
                "load_position_start": float(grid.position[0]),
            },
            tuned=axis.tuned,
            settings=axis.settings,
            reference=grid,
            metrics_window=(0.0, None),
            optimize=dict(optimize or {}),
            diagnose=dict(self.diagnose),
            model=axis.model,
            plant_parameters_file=axis.plant_parameters_file,
        )
