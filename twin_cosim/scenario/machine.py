"""A machine of several axes: the ``axes:`` scenario file read and checked once into the typed
:class:`MachineScenario`.

Layout (``axes`` is required, every other section optional)::

    name: xy_table
    description: free text
    axes:
      X:
        plant: {model: drive2mass, parameters: {}, parameters_file: x_plant.yaml}
        controller: {parameters: ft, settings: {}}
        limits: {velocity: 0.25, acceleration: 2.0, jerk: 40.0}    # m/s, m/s^2, m/s^3
      Y: {...}
      Z: {...}                          # optional
    interpolation:
      sample_period: 0.004              # s: the CNC's interpolation period
    program: part.nc                    # a part program (G-code), relative to the file
    run:
      settle: 0.2                       # s of standstill recorded after the path's end
      max_samples: 2400000              # position-loop samples a run may have at most
    optimize: {...}                     # contour tuning (twin_cosim.contour.tuning)
    diagnose: {...}                     # the diagnosis of each axis (twin_cosim.gap.settings)

``X`` and ``Y`` are required, ``Z`` optional. Each axis' ``plant`` and ``controller`` read as the
sections of a single-axis scenario (:mod:`~twin_cosim.scenario.plant_section`,
:mod:`~twin_cosim.scenario.controller_section`), and all axes must share the CNC's rates
(position- and speed-loop periods): the master steps them in lockstep. Every error names the file
and the full key path (``axes.Y.plant.parameters.backlash``).

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
from twin_cosim.reference import ReferenceError, ReferenceGrid, check_periods
from twin_cosim.scenario.controller_section import controller_section
from twin_cosim.scenario.loader import MAX_SAMPLES, find_scenario, read_top_level
from twin_cosim.scenario.plant_section import plant_section
from twin_cosim.scenario.resolved import Scenario
from twin_cosim.schema import Checker, load_yaml

AXIS_NAMES = ("X", "Y", "Z")
AXIS_KEYS = {"plant", "controller", "limits"}
MACHINE_KEYS = {
    "name",
    "description",
    "axes",
    "interpolation",
    "program",
    "run",
    "optimize",
    "diagnose",
}


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


DEFAULT_LIMITS = AxisLimits(velocity=0.25, acceleration=2.0, jerk=40.0)


def axes_section(check: Checker, data: Any) -> tuple[AxisSetup, ...]:
    """The checked axes of ``axes:``, in the order X, Y, Z."""
    axes = check.mapping(data, "axes", set(AXIS_NAMES))
    for required in ("X", "Y"):
        if required not in axes:
            raise check.fail(f"axes.{required}", "a section for this axis (X and Y are required)")
    found = tuple(
        _axis(
            check.within(f"axes.{name}"),
            name,
            check.mapping(axes[name], f"axes.{name}", AXIS_KEYS),
        )
        for name in AXIS_NAMES
        if name in axes
    )
    first = found[0].settings
    for axis in found[1:]:
        for rate in ("position_period", "speed_period"):
            if getattr(axis.settings, rate) != getattr(first, rate):
                raise check.fail(
                    f"axes.{axis.name}.controller.settings.{rate}",
                    f"the {rate} of axis {found[0].name} ({getattr(first, rate):g} s): the "
                    "master steps all axes in lockstep",
                    getattr(axis.settings, rate),
                )
    return found


def _axis(check: Checker, name: str, body: dict[str, Any]) -> AxisSetup:
    plant = plant_section(check, body.get("plant"))
    tuned, settings = controller_section(check, plant, body.get("controller"))
    return AxisSetup(
        name=name,
        model=plant.model,
        fmu=plant.fmu,
        plant_parameters=dict(plant.parameters),
        plant_parameters_file=plant.parameters_file,
        tuned=tuned,
        settings=settings,
        limits=_limits(check, body.get("limits")),
    )


def _limits(check: Checker, data: Any) -> AxisLimits:
    given = check.mapping(data, "limits", {"velocity", "acceleration", "jerk"})
    values = {
        key: check.number(
            given.get(key, getattr(DEFAULT_LIMITS, key)), f"limits.{key}", positive=True
        )
        for key in ("velocity", "acceleration", "jerk")
    }
    return AxisLimits(**values)


def is_machine_scenario(path: Path | str) -> bool:
    """Whether a scenario file (or shipped name) describes a machine (has ``axes:``)."""
    data = load_yaml(find_scenario(path))
    return isinstance(data, dict) and "axes" in data


def load_machine(path: Path | str) -> MachineScenario:
    """Load and check a machine scenario (a path or the name of a shipped one).

    Raises
    ------
    ScenarioError
        On malformed YAML, unknown keys, wrong types, non-finite or out-of-range values; the
        message names the file and the key path.
    """
    check, data, name = read_top_level(
        path, MACHINE_KEYS, "axes", "an axes section (X, Y and optionally Z)"
    )
    source = Path(check.source)
    axes = axes_section(check, data["axes"])
    interpolation = check.mapping(data.get("interpolation"), "interpolation", {"sample_period"})
    sample_period = check.number(
        interpolation.get("sample_period", 0.004), "interpolation.sample_period", positive=True
    )
    try:
        check_periods(sample_period, axes[0].settings.position_period)
    except ReferenceError as exc:
        raise check.fail("interpolation.sample_period", str(exc), sample_period) from None
    run = check.mapping(data.get("run"), "run", {"settle", "max_samples"})
    program = data.get("program")
    return MachineScenario(
        name=name,
        description=str(data.get("description", "")),
        source=source,
        axes=axes,
        sample_period=sample_period,
        program=None if program is None else source.parent / check.text(program, "program"),
        settle=check.number(run.get("settle", 0.2), "run.settle", minimum=0.0),
        max_samples=int(
            check.number(run.get("max_samples", MAX_SAMPLES), "run.max_samples", minimum=2)
        ),
        optimize=check.mapping(data.get("optimize"), "optimize"),
        diagnose=check.mapping(data.get("diagnose"), "diagnose"),
    )
