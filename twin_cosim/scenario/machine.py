"""A machine of several axes: the ``axes:`` scenario file read and checked once into the typed
:class:`MachineScenario`, and the geometric errors of the machine.

Layout (``axes`` is required, every other section optional)::

    name: xy_table
    description: free text
    axes:
      X:
        plant: {model: drive2mass, parameters: {}, parameters_file: x_plant.yaml}
        controller: {parameters: ft, settings: {}}
        limits: {velocity: 0.25, acceleration: 2.0, jerk: 40.0,    # m/s, m/s^2, m/s^3
                 travel: [-0.2, 0.2]}                              # m: soft limits (optional)
      Y: {...}
      Z: {...}                          # optional
    interpolation:
      sample_period: 0.004              # s: the CNC's interpolation period
      path_mode: G61                    # G61: exact stop at every block end; G64: blending
      tolerance: 5.0e-6                 # m: G64's P (Q: P/2), how far the path may leave a corner
      look_ahead: 200                   # blocks the planner looks ahead
    geometry: {...}                     # geometric errors (below)
    program: part.nc                    # a part program (G-code), relative to the file
    run:
      settle: 0.2                       # s of standstill recorded after the path's end
      max_samples: 2400000              # position-loop samples a run may have at most
    optimize: {...}                     # contour tuning (twin_cosim.contour.tuning)
    diagnose: {...}                     # the diagnosis of each axis (twin_cosim.gap.settings)

``X`` and ``Y`` are required, ``Z`` optional. Each axis' ``plant`` and ``controller`` read as the
sections of a single-axis scenario (:mod:`~twin_cosim.scenario.plant_parameters`,
:mod:`~twin_cosim.scenario.controller_section`), and all axes must share the CNC's rates
(position- and speed-loop periods): the master steps them in lockstep. Every error names the file
and the full key path (``axes.Y.plant.parameters.backlash``).

Each axis is a plant (model or FMU file, its parameters) with its own controller set and the
limits the interpolator must respect; :meth:`MachineScenario.axis_scenario` gives one axis as an
ordinary single-axis :class:`~twin_cosim.scenario.resolved.Scenario` once its reference is known
(the per-axis diagnosis and campaigns take that).

**Geometric errors** of a machine: where the tool point is, given the axes' positions.

Each axis' position is what its scale reads (the position the loop closes on). The tool point
that a ballbar or a part sees differs from it by the machine's geometry, the ``geometry:``
section of a machine scenario (every value optional, 0 by default)::

    geometry:
      squareness: 20.0                  # um/m: + when the angle between +X and +Y exceeds 90 deg
      scale: {X: 15.0, Y: -10.0}        # um/m: each axis' scale error (+: the tool goes further)
      straightness: {X: 4.0, Y: 0.0}    # um: each axis' bow over its travel (limits.travel),
                                        # + toward + of the other axis (X's toward +Y)
      cyclic: {X: {amplitude_um: 1.5, period_mm: 10.0}}   # each axis' cyclic (pitch) error

With the axes' positions x, y (m) and the errors in SI (scale s, squareness alpha in rad, bow
b over a travel of centre c and half-length h, cyclic amplitude A and period P)::

    x_s = x (1 + s_X) + A_X sin(2 pi x / P_X)       y_s = y (1 + s_Y) + A_Y sin(2 pi y / P_Y)
    x_t = x_s - alpha y_s + b_Y (1 - ((y - c_Y) / h_Y)^2)
    y_t = y_s + b_X (1 - ((x - c_X) / h_X)^2)

(first order in the errors: the +Y axis runs along (-alpha, 1), so that the angle between +X and
+Y is 90 deg + alpha; a straightness bow is 0 at both ends of the travel and b in its middle).
A Z axis has no geometric errors here.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fmu_build.build import build_fmu
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.plant_model import model_of, plant_model
from twin_cosim.reference import ReferenceError, ReferenceGrid, check_periods
from twin_cosim.scenario.controller_section import controller_section
from twin_cosim.scenario.loader import MAX_SAMPLES, find_scenario, read_top_level
from twin_cosim.scenario.plant_parameters import plant_section
from twin_cosim.scenario.resolved import Scenario, ScenarioFile
from twin_cosim.schema import Checker, ScenarioError, load_yaml

UM = 1e-6  # m per um
MM = 1e-3  # m per mm
PLANE = ("X", "Y")
GEOMETRY_KEYS = {"squareness", "scale", "straightness", "cyclic"}


@dataclass(frozen=True)
class CyclicError:
    """A cyclic error along one axis: the tool is off by ``amplitude sin(2 pi x / period)``.

    Attributes
    ----------
    amplitude : float
        Amplitude, m.
    period : float
        Period along the axis, m (a screw's lead, a scale's grating period).
    """

    amplitude: float
    period: float


@dataclass(frozen=True)
class MachineGeometry:
    """The geometric errors between the axes' positions and the tool point (module docstring).

    Attributes
    ----------
    squareness : float
        Squareness of Y to X, rad: + when the angle between +X and +Y exceeds 90 deg.
    scale : dict
        Axis name -> scale error, 1 (m/m).
    straightness : dict
        Axis name -> bow over its travel, m (+ toward + of the other axis).
    travel : dict
        Axis name -> (low, high) travel, m: where the bow of an axis with straightness is 0.
    cyclic : dict
        Axis name -> its :class:`CyclicError`.
    """

    squareness: float = 0.0
    scale: dict[str, float] = field(default_factory=dict)
    straightness: dict[str, float] = field(default_factory=dict)
    travel: dict[str, tuple[float, float]] = field(default_factory=dict)
    cyclic: dict[str, CyclicError] = field(default_factory=dict)

    @property
    def is_ideal(self) -> bool:
        """Whether the tool point is the axes' positions (no error at all)."""
        return (
            self.squareness == 0.0
            and not any(self.scale.values())
            and not any(self.straightness.values())
            and not any(c.amplitude for c in self.cyclic.values())
        )

    def _bow(self, axis: str, position: np.ndarray) -> np.ndarray:
        """The bow of ``axis`` at its positions (m): 0 at both ends of the travel."""
        bow = self.straightness.get(axis, 0.0)
        if bow == 0.0:
            return np.zeros_like(position)
        low, high = self.travel[axis]
        centre, half = (low + high) / 2, (high - low) / 2
        return bow * (1.0 - ((position - centre) / half) ** 2)

    def _along(self, axis: str, position: np.ndarray) -> np.ndarray:
        """The axis' own direction: its scale and cyclic errors applied (m)."""
        moved = position * (1.0 + self.scale.get(axis, 0.0))
        cyclic = self.cyclic.get(axis)
        if cyclic is not None and cyclic.amplitude:
            moved = moved + cyclic.amplitude * np.sin(2 * math.pi * position / cyclic.period)
        return moved

    def tool_point(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tool point (m) where the X and Y axes read ``x`` and ``y`` (m)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        if self.is_ideal:
            return x, y
        x_s, y_s = self._along("X", x), self._along("Y", y)
        return x_s - self.squareness * y_s + self._bow("Y", y), y_s + self._bow("X", x)

    def as_dict(self) -> dict[str, Any]:
        """The section as written (um/m, um, mm), for JSON files."""
        return {
            "squareness": self.squareness / UM,
            "scale": {axis: value / UM for axis, value in self.scale.items()},
            "straightness": {axis: value / UM for axis, value in self.straightness.items()},
            "cyclic": {
                axis: {"amplitude_um": c.amplitude / UM, "period_mm": c.period / MM}
                for axis, c in self.cyclic.items()
            },
        }


def geometry_section(
    check: Checker, data: Any, travel: dict[str, tuple[float, float] | None]
) -> MachineGeometry:
    """The checked ``geometry:`` section; ``travel`` (m) is each axis' ``limits.travel``, which
    a straightness bow needs.

    Raises
    ------
    ScenarioError
        Naming the file and the key, e.g. ``geometry.scale.X: expected a number``.
    """
    given = check.mapping(data, "geometry", GEOMETRY_KEYS)
    scale = _per_axis(check, given.get("scale"), "geometry.scale")
    bows = _per_axis(check, given.get("straightness"), "geometry.straightness")
    for axis, bow in bows.items():
        if bow and travel.get(axis) is None:
            raise check.fail(
                f"axes.{axis}.limits.travel",
                f"a travel [low, high] in m: geometry.straightness.{axis} is a bow over it",
            )
    cyclic = {}
    for axis, value in check.mapping(given.get("cyclic"), "geometry.cyclic", set(PLANE)).items():
        key = f"geometry.cyclic.{axis}"
        entry = check.mapping(value, key, {"amplitude_um", "period_mm"})
        for name in ("amplitude_um", "period_mm"):
            if name not in entry:
                raise check.fail(f"{key}.{name}", "a number (amplitude um, period mm)")
        cyclic[axis] = CyclicError(
            amplitude=check.number(entry["amplitude_um"], f"{key}.amplitude_um", minimum=0.0) * UM,
            period=check.number(entry["period_mm"], f"{key}.period_mm", positive=True) * MM,
        )
    return MachineGeometry(
        squareness=check.number(given.get("squareness", 0.0), "geometry.squareness") * UM,
        scale={axis: value * UM for axis, value in scale.items()},
        straightness={axis: value * UM for axis, value in bows.items()},
        travel={axis: span for axis, span in travel.items() if span is not None},
        cyclic=cyclic,
    )


def _per_axis(check: Checker, data: Any, key: str) -> dict[str, float]:
    """A mapping of X and Y to numbers."""
    values = check.mapping(data, key, set(PLANE))
    return {axis: check.number(value, f"{key}.{axis}") for axis, value in values.items()}


AXIS_NAMES = ("X", "Y", "Z")
SINGLE_AXIS_KEYS = {"plant", "controller", "reference"}  # a single-axis scenario's sections
AXIS_KEYS = {"plant", "controller", "limits"}
MACHINE_KEYS = {
    "name",
    "description",
    "axes",
    "interpolation",
    "geometry",
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
    travel : tuple or None
        Soft limits (low, high) of the axis' position, m; None: no limit.
    """

    velocity: float
    acceleration: float
    jerk: float
    travel: tuple[float, float] | None = None


PATH_MODES = ("G61", "G64")
LOOK_AHEAD = 200  # blocks the planner looks ahead by default


@dataclass(frozen=True)
class PathControl:
    """How the path passes the joins of its blocks (RS274/NGC's path control mode).

    Attributes
    ----------
    mode : str
        ``G61``: exact stop, every block ends at rest; ``G64``: blending, the path keeps its
        speed through tangent joins and rounds corners within ``tolerance``.
    tolerance : float
        G64's P: how far the path may leave a programmed corner, m; ``inf`` for G64 without P
        (the best speed, the corner rounded as far as the blocks allow).
    merge_tolerance : float
        G64's Q, LinuxCNC's naive CAM tolerance: consecutive straight moves in the XY plane
        whose corners lie within it of one straight line are traversed as that line, m (P/2
        when Q is not given, below P; the corners of merged lines blend within P - Q, so that
        the path stays within P; 0 for G64 without P: none merged).
    """

    mode: str = "G61"
    tolerance: float = math.inf
    merge_tolerance: float = 0.0

    @property
    def blends(self) -> bool:
        """Whether joins are blended (G64)."""
        return self.mode == "G64"

    def describe(self) -> str:
        """``G61`` or ``G64 P<tolerance in mm>``, as a program writes it."""
        if not self.blends:
            return "G61"
        if math.isinf(self.tolerance):
            return "G64"
        written = f"G64 P{self.tolerance * 1e3:g}"
        if self.merge_tolerance != self.tolerance / 2:
            written += f" Q{self.merge_tolerance * 1e3:g}"
        return written


EXACT_STOP = PathControl("G61")


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
        :mod:`twin_cosim.scenario.plant_parameters`.
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

    def screw_lead(self) -> float:
        """Carriage travel per screw revolution, m: 2 pi times the travel per motor radian
        times the motor radians per screw radian (the plant card's ``motor_per_screw``)."""
        card = plant_model(self.model_name())
        values = {**card.start_values(), **self.plant_parameters}
        return 2 * math.pi * self.settings.travel_per_rad * card.motor_per_screw(values)


@dataclass(frozen=True)
class MachineScenario(ScenarioFile):
    """A loaded, checked scenario of several axes (its name, description and file:
    :class:`~twin_cosim.scenario.resolved.ScenarioFile`).

    Attributes
    ----------
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
    path_control : PathControl
        The path control mode a program runs with until it sets its own (``G61``, ``G64``).
    look_ahead : int
        Blocks the planner looks ahead: every join's speed allows a stop within them.
    geometry : MachineGeometry
        The geometric errors between the axes' positions and the tool point.
    optimize : dict
        The raw ``optimize`` section (contour tuning).
    diagnose : dict
        The raw ``diagnose`` section (the diagnosis of each axis).
    """

    axes: tuple[AxisSetup, ...]
    sample_period: float
    program: Path | None = None
    settle: float = 0.2
    max_samples: int = 2_400_000
    path_control: PathControl = EXACT_STOP
    look_ahead: int = LOOK_AHEAD
    geometry: MachineGeometry = MachineGeometry()
    optimize: dict[str, Any] = field(default_factory=dict)
    diagnose: dict[str, Any] = field(default_factory=dict)

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The axes' names, in order."""
        return tuple(a.name for a in self.axes)

    @property
    def limits(self) -> dict[str, AxisLimits]:
        """Each axis' limits by name, in order."""
        return {a.name: a.limits for a in self.axes}

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
    given = check.mapping(data, "limits", {"velocity", "acceleration", "jerk", "travel"})
    values = {
        key: check.number(
            given.get(key, getattr(DEFAULT_LIMITS, key)), f"limits.{key}", positive=True
        )
        for key in ("velocity", "acceleration", "jerk")
    }
    return AxisLimits(**values, travel=_travel(check, given.get("travel")))


def _travel(check: Checker, data: Any) -> tuple[float, float] | None:
    """The soft limits [low, high] (m) around the origin, where programs start; None: none."""
    if data is None:
        return None
    if not (isinstance(data, list) and len(data) == 2):
        raise check.fail("limits.travel", "[low, high] in m", data)
    low = check.number(data[0], "limits.travel[0]")
    high = check.number(data[1], "limits.travel[1]")
    if not low <= 0.0 <= high or low == high:
        raise check.fail(
            "limits.travel", "[low, high] in m with low <= 0 <= high, low < high", data
        )
    return (low, high)


def _interpolation(check: Checker, data: Any) -> tuple[float, PathControl, int]:
    """The ``interpolation`` section: sample period (s), path control, look-ahead (blocks)."""
    given = check.mapping(
        data, "interpolation", {"sample_period", "path_mode", "tolerance", "look_ahead"}
    )
    period = check.number(
        given.get("sample_period", 0.004), "interpolation.sample_period", positive=True
    )
    mode = given.get("path_mode", "G61")
    if mode not in PATH_MODES:
        raise check.fail("interpolation.path_mode", f"one of {list(PATH_MODES)}", mode)
    tolerance = math.inf
    if "tolerance" in given:
        if mode != "G64":
            raise check.fail("interpolation.tolerance", "no tolerance with G61 (exact stop)")
        tolerance = check.number(given["tolerance"], "interpolation.tolerance", positive=True)
    look_ahead = check.number(given.get("look_ahead", LOOK_AHEAD), "interpolation.look_ahead")
    if look_ahead != int(look_ahead) or look_ahead < 1:
        raise check.fail("interpolation.look_ahead", "a whole number of blocks >= 1", look_ahead)
    merge = 0.0 if math.isinf(tolerance) else tolerance / 2
    return period, PathControl(mode, tolerance, merge), int(look_ahead)


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
    source = find_scenario(path)
    loaded = load_yaml(source)
    if isinstance(loaded, dict) and "axes" not in loaded and SINGLE_AXIS_KEYS & set(loaded):
        raise ScenarioError(
            f"{source}: a single-axis scenario (plant, controller, reference); this command "
            "needs a machine scenario, with axes: (X, Y and optionally Z), e.g. xy_table"
        )
    check, data, name = read_top_level(
        source, MACHINE_KEYS, "axes", "an axes section (X, Y and optionally Z)"
    )
    axes = axes_section(check, data["axes"])
    sample_period, path_control, look_ahead = _interpolation(check, data.get("interpolation"))
    geometry = geometry_section(
        check, data.get("geometry"), {a.name: a.limits.travel for a in axes}
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
        path_control=path_control,
        look_ahead=look_ahead,
        geometry=geometry,
        optimize=check.mapping(data.get("optimize"), "optimize"),
        diagnose=check.mapping(data.get("diagnose"), "diagnose"),
    )
