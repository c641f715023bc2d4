"""Scenario files: plant, controller, reference and run settings in one YAML file, checked on load.

Layout (every section but ``reference`` is optional)::

    name: reference1
    description: free text
    plant:
      model: drive2mass         # a folder of models/ (the default), built on first use; or
      fmu: other.fmu            # an FMU file, relative to the scenario file
      parameters: {backlash: 12.2e-6}        # FMU parameters by name
      parameters_file: plant.yaml            # a calibrated plant (twin_cosim.plant_parameters),
                                             # relative to the scenario file; its names must not
                                             # be repeated in parameters
    controller:
      parameters: {Kp_pos: 66.667, ...}      # the six tuned parameters, or the name of a set of
                                             # the paper's Table 3 (ft, ga, ce, sa); default: ft
      settings: {current_limit: 20.0, ...}   # see twin_cosim.controller.ControllerSettings
    reference:
      sample_period: 0.004                   # s
      start_position: 0.0                    # m
      segments:                              # or  csv: samples.csv  (columns t [s], x_ref [m])
        - dwell: 0.5                         # s
        - move: {to: 0.02, velocity: 0.02, acceleration: 0.5}   # m, m/s, m/s^2
        - oscillation: {amplitude: 0.01, frequency: 1.0, cycles: 2}  # m, Hz, 1
        - ramp: {velocity: 0.01, acceleration: 0.1, duration: 1.0}   # m/s, m/s^2, s
    run:
      metrics_window: [0.0, null]            # s; null: to the end
      max_samples: 2400000                   # position-loop samples a run may have at most
    optimize: {...}                          # see twin_cosim.optimize.config
    diagnose: {...}                          # see twin_cosim.gap.settings.settings_from

The controller's plant facts (travel per radian, inertia, torque constant, friction) come from
the plant model's start values and ``plant.parameters`` (:mod:`twin_cosim.plant_facts`) unless
``controller.settings`` sets them.

A measured reference (``reference.measured``, a file relative to the scenario) is looked up first
by its file name in the data folder given by ``--data DIR`` or the environment variable
``TWIN_COSIM_DATA``; ``reference.data_source`` says what the data is and where to get it, for the
error when it is missing.

Scenarios shipped with the package are found by name (``reference1``) as well as by path.

Every error names the file and the key path, and says what was expected. ``name`` (used as the
default output folder) must be a plain file name, ``plant.model`` one of the project's models, and
the size of a run is checked before anything is allocated (``run.max_samples``).

A scenario may name an FMU, which is native code that runs in this process: use scenario files
from trusted sources only.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from fmu_build.build import DEFAULT_MODEL, BuildError, available_models, build_fmu
from twin_cosim import paper
from twin_cosim.controller import TUNED_NAMES, ControllerSettings, TunedParameters
from twin_cosim.environment import DATA_ENV
from twin_cosim.measured import MeasuredDataError, MeasuredRun, read_measured
from twin_cosim.plant_facts import DRIVE_FACTS, drive_facts, fmu_identity, model_start_values
from twin_cosim.reference import (
    Dwell,
    Move,
    Oscillation,
    Ramp,
    ReferenceError,
    ReferenceGrid,
    check_periods,
    interpolate,
    read_reference_csv,
    sample_segments,
    segments_duration,
)

TOP_KEYS = {
    "name",
    "description",
    "plant",
    "controller",
    "reference",
    "run",
    "optimize",
    "diagnose",
}


NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")
MAX_SAMPLES = 2_400_000  # position-loop samples of a run: 10 min at 250 us


class ScenarioError(ValueError):
    """A scenario file is invalid; the message names the file, the key and what was expected."""


class _Loader(yaml.SafeLoader):
    """YAML loader that also reads 1e6 and 2.5e-3 (no dot or no exponent sign) as floats."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$"
    ),
    list("-+0123456789."),
)


def load_yaml(path: Path) -> Any:
    """Read a YAML file; ScenarioError names the file on a read or syntax error."""
    try:
        return yaml.load(Path(path).read_text(), Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except FileNotFoundError as exc:
        raise ScenarioError(f"{path}: file not found") from exc
    except IsADirectoryError as exc:
        raise ScenarioError(f"{path}: is a folder, not a YAML file") from exc
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not a text (YAML) file: {exc}") from exc
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{path}: malformed YAML: {exc}") from exc


@dataclass(frozen=True)
class Scenario:
    """A loaded, checked scenario.

    Attributes
    ----------
    reference : ReferenceGrid
        The reference on the position-loop grid.
    plant_parameters : dict
        FMU parameter values by name (``load_position_start`` defaults to the reference start).
    metrics_window : tuple
        (t0, tF) in s for the metrics; tF None means the end of the run.
    optimize : dict
        The raw ``optimize`` section, checked by :mod:`twin_cosim.optimize.config`.
    measured : Path or None
        The measured run the reference was taken from (``reference.measured``); ``twin
        simulate`` compares the replay with it.
    model : str or None
        The plant model (folder of models/) the scenario was made for; None for an FMU file.
    disturbance : numpy.ndarray or None
        Disturbance input (N.m, or N on a linear axis) per position-loop sample.
    command_disturbance : numpy.ndarray or None
        Signal added to the controller's output before the plant, per position-loop sample
        (the command's unit: A, or V for EMPS).
    disturbance_in_record : bool
        The measured command includes ``command_disturbance`` (the twin's recorded command then
        does too).
    """

    name: str
    description: str
    source: Path
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


class _Checker:
    """Helpers that raise ScenarioError naming the file and the key path."""

    def __init__(self, source: Path) -> None:
        self.source = source

    def fail(self, key: str, expected: str, got: Any = None) -> ScenarioError:
        suffix = "" if got is None else f", got {got!r}"
        return ScenarioError(f"{self.source}: {key}: expected {expected}{suffix}")

    def mapping(self, value: Any, key: str, allowed: set[str] | None = None) -> dict[str, Any]:
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(key, "a mapping", value)
        if allowed is not None:
            unknown = sorted(set(value) - allowed)
            if unknown:
                raise ScenarioError(
                    f"{self.source}: {key}: unknown key(s) {unknown}; allowed: {sorted(allowed)}"
                )
        return value

    def number(
        self, value: Any, key: str, minimum: float | None = None, positive: bool = False
    ) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, "a number", value)
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(key, "a finite number", value)
        if positive and value <= 0:
            raise self.fail(key, "a number > 0", value)
        if minimum is not None and value < minimum:
            raise self.fail(key, f"a number >= {minimum}", value)
        return value


# Segment kinds with mapping bodies: class and fields (name, unit, must be > 0), in order.
SEGMENT_FIELDS = {
    "move": (
        Move,
        (("to", "m", False), ("velocity", "m/s", True), ("acceleration", "m/s^2", True)),
    ),
    "oscillation": (
        Oscillation,
        (("amplitude", "m", False), ("frequency", "Hz", True), ("cycles", "1", True)),
    ),
    "ramp": (
        Ramp,
        (("velocity", "m/s", False), ("acceleration", "m/s^2", True), ("duration", "s", True)),
    ),
}


def _segment(check: _Checker, item: Any, key: str):
    if not isinstance(item, dict) or len(item) != 1:
        raise check.fail(key, "a one-key mapping: dwell, move, oscillation or ramp", item)
    ((kind, body),) = item.items()
    if kind == "dwell":
        return Dwell(check.number(body, f"{key}.dwell", positive=True))
    if kind not in SEGMENT_FIELDS:
        raise check.fail(key, "one of dwell, move, oscillation, ramp", kind)
    cls, spec = SEGMENT_FIELDS[kind]
    body = check.mapping(body, f"{key}.{kind}", {name for name, _, _ in spec})
    values = []
    for name, unit, positive in spec:
        if name not in body:
            raise check.fail(f"{key}.{kind}.{name}", f"a value in {unit}")
        values.append(check.number(body[name], f"{key}.{kind}.{name}", positive=positive))
    return cls(*values)


@dataclass(frozen=True)
class _Reference:
    grid: ReferenceGrid
    start: float
    measured: Path | None = None
    plant_start: float | None = None
    disturbance: np.ndarray | None = None
    disturbance_spec: dict[str, Any] = field(default_factory=dict)
    command_disturbance: np.ndarray | None = None


# Where a measured run's disturbance signal enters the loop (reference.disturbance.enters).
DISTURBANCE_ENTRIES = ("disturbance_input", "command")


def _run_disturbance(
    run: MeasuredRun, spec: dict[str, Any], grid: ReferenceGrid
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(disturbance input, command disturbance) of a run: ``gain`` x its ``variable`` on the
    grid, at the plant's disturbance input (N.m, or N) or added to the command (its unit).

    A run without that variable (e.g. the EMPS estimation run, which has no pulses) has none.
    """
    values = run.extra.get(spec["variable"]) if spec else None
    if not isinstance(values, np.ndarray):
        return None, None
    signal = spec["gain"] * np.interp(grid.time, run.t, values)
    return (signal, None) if spec["enters"] == "disturbance_input" else (None, signal)


def _disturbance_spec(check: _Checker, data: Any) -> dict[str, Any]:
    """The signal convention of ``reference.disturbance`` (empty when absent)."""
    keys = {"variable", "gain", "enters", "in_recorded_command"}
    spec = check.mapping(data, "reference.disturbance", keys)
    if not spec:
        return {}
    variable = spec.get("variable")
    if not isinstance(variable, str):
        raise check.fail("reference.disturbance.variable", "the name of a signal", variable)
    enters = spec.get("enters", "disturbance_input")
    if enters not in DISTURBANCE_ENTRIES:
        raise check.fail(
            "reference.disturbance.enters", f"one of {list(DISTURBANCE_ENTRIES)}", enters
        )
    recorded = spec.get("in_recorded_command", False)
    if not isinstance(recorded, bool):
        raise check.fail("reference.disturbance.in_recorded_command", "true or false", recorded)
    if recorded and enters != "command":
        raise check.fail(
            "reference.disturbance.in_recorded_command",
            "false unless the disturbance enters at the command (enters: command)",
            recorded,
        )
    return {
        "variable": variable,
        "gain": check.number(spec.get("gain", 1.0), "reference.disturbance.gain"),
        "enters": enters,
        "in_recorded_command": recorded,
    }


def data_dir() -> Path | None:
    """The data folder given by ``--data`` or the environment variable ``TWIN_COSIM_DATA``."""
    value = os.environ.get(DATA_ENV)
    return Path(value) if value else None


def _measured_path(check: _Checker, data: dict[str, Any]) -> Path:
    """The measured run file: by name in the data folder, else relative to the scenario."""
    relative = check.source.parent / str(data["measured"])
    folder = data_dir()
    candidates = ([folder / relative.name] if folder is not None else []) + [relative]
    for path in candidates:
        if path.is_file():
            return path
    about = data.get("data_source")
    raise ScenarioError(
        f"{check.source}: reference.measured: {relative.name} not found (looked in "
        f"{', '.join(os.path.normpath(p.parent) for p in candidates)}). "
        + (f"{about} " if about else "")
        + f"Give the folder that holds {relative.name} with --data DIR or the environment "
        f"variable {DATA_ENV}=DIR."
    )


def _check_size(
    check: _Checker, duration: float, position_period: float, max_samples: int, what: str
) -> None:
    """Refuse, before allocating it, a run with more position-loop samples than allowed."""
    samples = duration / position_period + 1
    if samples > max_samples:
        raise ScenarioError(
            f"{check.source}: {what}: {duration:g} s at the position-loop period "
            f"{position_period:g} s makes {samples:.4g} samples, more than run.max_samples = "
            f"{max_samples}; shorten the reference or raise run.max_samples"
        )


def _from_measured(
    check: _Checker, data: dict[str, Any], position_period: float, max_samples: int
) -> _Reference:
    """The reference (and disturbance) of a measured run file (.csv or EMPS .mat)."""
    path = _measured_path(check, data)
    try:
        run = read_measured(path)
    except MeasuredDataError as exc:
        raise ScenarioError(f"{check.source}: reference.measured: {exc}") from exc
    if abs(run.t[0]) > 0.5 * run.period:
        raise check.fail("reference.measured", "a run whose time starts at 0 s", float(run.t[0]))
    _check_size(check, float(run.t[-1]), position_period, max_samples, "reference.measured")
    try:
        grid = interpolate(run.x_ref, run.period, position_period)
    except ReferenceError as exc:
        raise ScenarioError(f"{check.source}: reference: {exc}") from exc
    spec = _disturbance_spec(check, data.get("disturbance"))
    at_input, at_command = _run_disturbance(run, spec, grid)
    return _Reference(grid, float(run.x_ref[0]), path, float(run.x[0]), at_input, spec, at_command)


def _reference(check: _Checker, data: Any, position_period: float, max_samples: int) -> _Reference:
    data = check.mapping(
        data,
        "reference",
        {
            "sample_period",
            "start_position",
            "segments",
            "csv",
            "measured",
            "disturbance",
            "data_source",
        },
    )
    sources = [key for key in ("segments", "csv", "measured") if key in data]
    if len(sources) != 1:
        raise check.fail("reference", "exactly one of 'segments', 'csv' or 'measured'")
    if "measured" in data:
        return _from_measured(check, data, position_period, max_samples)
    for key in ("disturbance", "data_source"):
        if key in data:
            raise check.fail(f"reference.{key}", "a 'measured' reference to go with it")
    sample_period = check.number(
        data.get("sample_period", 0.004), "reference.sample_period", positive=True
    )
    start = check.number(data.get("start_position", 0.0), "reference.start_position")
    try:
        check_periods(sample_period, position_period)
        if "csv" in data:
            samples = read_reference_csv(check.source.parent / str(data["csv"]), sample_period)
            duration = (len(samples) - 1) * sample_period
            _check_size(check, duration, position_period, max_samples, "reference.csv")
            start = float(samples[0])
        else:
            segments = data["segments"]
            if not isinstance(segments, list) or not segments:
                raise check.fail("reference.segments", "a non-empty list", segments)
            parsed = [
                _segment(check, s, f"reference.segments[{i}]") for i, s in enumerate(segments)
            ]
            duration = segments_duration(parsed, start)
            _check_size(check, duration, position_period, max_samples, "reference.segments")
            if duration < sample_period:
                raise check.fail(
                    "reference.sample_period",
                    f"at most the reference's duration ({duration:g} s), so that it has two "
                    "samples or more",
                    sample_period,
                )
            samples = sample_segments(parsed, sample_period, start)
        return _Reference(interpolate(samples, sample_period, position_period), start)
    except ReferenceError as exc:
        raise ScenarioError(f"{check.source}: reference: {exc}") from exc


def _tuned(data: Any, where: str) -> TunedParameters:
    """Tuned parameters from a mapping, or the name of a set of the paper's Table 3."""
    if isinstance(data, str):
        if data.lower() not in paper.TABLE3:
            raise ScenarioError(
                f"{where}: expected the six parameters or a set of Table 3 {sorted(paper.TABLE3)}"
                f", got {data!r}"
            )
        return paper.TABLE3[data.lower()]
    return tuned_from_mapping(data, where)


def tuned_from_mapping(data: Any, where: str) -> TunedParameters:
    """The six tuned parameters from a mapping that must hold exactly those names.

    Raises
    ------
    ScenarioError
        Naming ``where`` (file and key) on a missing, unknown or invalid value.
    """
    if not isinstance(data, dict):
        raise ScenarioError(f"{where}: expected a mapping of {list(TUNED_NAMES)}")
    missing = [n for n in TUNED_NAMES if n not in data]
    unknown = sorted(set(data) - set(TUNED_NAMES))
    if missing or unknown:
        raise ScenarioError(
            f"{where}: missing {missing}, unknown {unknown}; expected exactly {list(TUNED_NAMES)}"
        )
    values = {}
    for name in TUNED_NAMES:
        value = data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f"{where}.{name}: expected a number, got {value!r}")
        values[name] = float(value)
    try:
        return TunedParameters(**values)
    except ValueError as exc:
        raise ScenarioError(f"{where}: {exc}") from exc


def packaged_scenarios_dir() -> Path:
    """The shipped scenarios: ``twin_cosim/scenarios`` of a wheel, else ``scenarios/``."""
    packaged = Path(__file__).resolve().parent / "scenarios"
    return packaged if packaged.is_dir() else Path(__file__).resolve().parents[1] / "scenarios"


def find_scenario(spec: Path | str) -> Path:
    """A scenario file from a path, or from the name of a shipped scenario (``reference1``).

    Raises
    ------
    ScenarioError
        When ``spec`` is neither an existing file nor the name of a shipped scenario.
    """
    path = Path(spec)
    if path.is_file() or path.suffix or len(path.parts) > 1:
        return path
    shipped = packaged_scenarios_dir() / f"{path.name}.yaml"
    if shipped.is_file():
        return shipped
    names = sorted(p.stem for p in packaged_scenarios_dir().glob("*.yaml"))
    raise ScenarioError(f"{spec}: neither a scenario file nor a shipped scenario {names}")


def _plant_facts(
    check: _Checker, model: str | None, fmu: Path | None, parameters: dict[str, float]
) -> dict[str, float]:
    """The drive's plant facts from the plant's start values and the scenario's parameters."""
    try:
        if model is not None:
            starts = model_start_values(model)
        elif fmu is not None and fmu.is_file():
            starts = fmu_identity(fmu)[2]
        else:
            starts = {}
    except Exception as exc:  # a broken FMU is reported when it is loaded to run
        raise ScenarioError(f"{check.source}: plant: cannot read its parameters: {exc}") from exc
    return drive_facts({**starts, **parameters})


def load_scenario(path: Path | str) -> Scenario:
    """Load and check a scenario file (a path or the name of a shipped scenario).

    A plant ``model`` whose FMU is not built yet is built here, with a note on stderr.

    Raises
    ------
    ScenarioError
        On malformed YAML, unknown keys, wrong types, non-finite or out-of-range values.
    """
    source = find_scenario(path)
    check = _Checker(source)
    data = check.mapping(load_yaml(source), "(top level)", TOP_KEYS)
    if "reference" not in data:
        raise check.fail("reference", "a reference section")
    name = str(data.get("name", source.stem))
    if "name" in data and not NAME_PATTERN.fullmatch(name):
        raise check.fail(
            "name",
            "a plain file name (letters, digits, '.', '_', '-'; at most 100; no folders), "
            "used as the default output folder",
            name,
        )
    plant = check.mapping(
        data.get("plant"), "plant", {"fmu", "model", "parameters", "parameters_file"}
    )
    plant_parameters = {
        str(k): check.number(v, f"plant.parameters.{k}")
        for k, v in check.mapping(plant.get("parameters"), "plant.parameters").items()
    }
    if "fmu" in plant and "model" in plant:
        raise check.fail(
            "plant", "either 'fmu' (a file) or 'model' (a folder of models/), not both"
        )
    fmu = plant.get("fmu")
    fmu_path = None if fmu is None else (source.parent / str(fmu))
    model = None if fmu is not None else str(plant.get("model", DEFAULT_MODEL))
    if "model" in plant:
        if plant["model"] not in available_models():
            raise check.fail(
                "plant.model", f"one of the project's models {available_models()}", plant["model"]
            )
        try:
            fmu_path = build_fmu(model, announce=True)
        except BuildError as exc:
            raise ScenarioError(f"{source}: plant.model: {exc}") from exc
    parameters_file = None
    if "parameters_file" in plant:
        parameters_file = source.parent / str(plant["parameters_file"])
        plant_parameters = _with_parameters_file(check, plant_parameters, parameters_file, fmu_path)
    control = check.mapping(data.get("controller"), "controller", {"parameters", "settings"})
    tuned = _tuned(control.get("parameters", "ft"), f"{source}: controller.parameters")
    setting_names = {f.name for f in fields(ControllerSettings)}
    raw_settings = check.mapping(control.get("settings"), "controller.settings", setting_names)
    facts = _plant_facts(check, model, fmu_path, plant_parameters)
    try:
        settings = ControllerSettings(
            **{name: facts[name] for name in DRIVE_FACTS if name in facts}
            | {k: check.number(v, f"controller.settings.{k}") for k, v in raw_settings.items()}
        )
    except ValueError as exc:
        raise ScenarioError(f"{source}: controller.settings: {exc}") from exc
    run = check.mapping(data.get("run"), "run", {"metrics_window", "max_samples"})
    max_samples = check.number(run.get("max_samples", MAX_SAMPLES), "run.max_samples", minimum=2)
    chosen = _reference(check, data["reference"], settings.position_period, int(max_samples))
    reference = chosen.grid
    plant_parameters.setdefault(
        "load_position_start", chosen.start if chosen.plant_start is None else chosen.plant_start
    )
    window = run.get("metrics_window", [0.0, None])
    if not isinstance(window, list) or len(window) != 2:
        raise check.fail("run.metrics_window", "[t0, tF] in s (tF may be null)", window)
    t0 = check.number(window[0], "run.metrics_window[0]", minimum=0.0)
    t_end = None if window[1] is None else check.number(window[1], "run.metrics_window[1]")
    if t_end is not None and not t0 < t_end <= reference.duration + 1e-9:
        raise check.fail("run.metrics_window", f"0 <= t0 < tF <= {reference.duration:g} s", window)
    return Scenario(
        name=name,
        description=str(data.get("description", "")),
        source=source,
        fmu=fmu_path,
        plant_parameters=plant_parameters,
        tuned=tuned,
        settings=settings,
        reference=reference,
        metrics_window=(t0, t_end),
        optimize=check.mapping(data.get("optimize"), "optimize"),
        diagnose=check.mapping(data.get("diagnose"), "diagnose"),
        measured=chosen.measured,
        disturbance=chosen.disturbance,
        disturbance_spec=chosen.disturbance_spec,
        command_disturbance=chosen.command_disturbance,
        disturbance_in_record=bool(chosen.disturbance_spec.get("in_recorded_command", False)),
        model=model,
        plant_parameters_file=parameters_file,
    )


def plant_mismatch(scenario: Scenario, fmu: Path) -> str | None:
    """A warning when ``fmu`` is not the plant model the scenario was made for, else None.

    The scenario names its model (``plant.model``, drive2mass by default) or its FMU
    (``plant.fmu``); another model identifier or another set of variables in ``fmu`` is a
    mismatch: the scenario's controller settings and plant parameters were chosen for another
    plant.
    """
    from twin_cosim.plant_facts import model_variable_names

    if scenario.model is not None:
        expected, expected_names = scenario.model, model_variable_names(scenario.model)
    elif scenario.fmu is not None and scenario.fmu.is_file():
        expected, expected_names, _ = fmu_identity(scenario.fmu)
    else:
        return None
    try:
        identifier, names, _ = fmu_identity(Path(fmu))
    except Exception:  # not readable: Plant reports it when the FMU is loaded
        return None
    if identifier == expected and names == expected_names:
        return None
    differences = []
    if names != expected_names:
        missing, extra = sorted(expected_names - names), sorted(names - expected_names)
        differences.append(
            f"variables missing: {missing[:5]}{' ...' if len(missing) > 5 else ''}, "
            f"variables added: {extra[:5]}{' ...' if len(extra) > 5 else ''}"
        )
    return (
        f"{scenario.source} was made for the plant model {expected!r}, but {fmu} is model "
        f"{identifier!r}" + (f" ({differences[0]})" if differences else "") + ": its controller "
        "settings and plant parameters were chosen for another plant"
    )


def _with_parameters_file(
    check: _Checker, parameters: dict[str, float], path: Path, fmu: Path | None
) -> dict[str, float]:
    """The scenario's plant parameters plus those of ``plant.parameters_file`` (no name twice)."""
    from twin_cosim.plant_parameters import PlantParametersError, fmu_model, read_plant_parameters

    try:
        calibrated = read_plant_parameters(path, fmu_model(fmu)).parameters
    except PlantParametersError as exc:
        raise ScenarioError(f"{check.source}: plant.parameters_file: {exc}") from exc
    twice = sorted(set(parameters) & set(calibrated))
    if twice:
        raise check.fail(
            "plant.parameters", f"no name also set by plant.parameters_file {path}", twice
        )
    return {**calibrated, **parameters}


def for_measured_run(scenario: Scenario, run: MeasuredRun) -> Scenario:
    """The scenario as it applies to another measured run.

    A scenario whose reference comes from a measured file (``reference.measured``) applies to
    another run of the same machine with that run's reference, start position and disturbance
    (e.g. the EMPS validation run with its force pulses); any other scenario is returned as it is.
    """
    if scenario.measured is None or Path(run.source).resolve() == scenario.measured.resolve():
        return scenario
    if abs(run.t[0]) > 0.5 * run.period:
        raise ScenarioError(f"{run.source}: time must start at 0 s to follow its own reference")
    try:
        grid = interpolate(run.x_ref, run.period, scenario.settings.position_period)
    except ReferenceError as exc:
        raise ScenarioError(f"{run.source}: reference: {exc}") from exc
    at_input, at_command = _run_disturbance(run, scenario.disturbance_spec, grid)
    return dataclasses.replace(
        scenario,
        reference=grid,
        plant_parameters={**scenario.plant_parameters, "load_position_start": float(run.x[0])},
        measured=Path(run.source),
        disturbance=at_input,
        command_disturbance=at_command,
    )


def load_tuned_parameters(spec: str) -> TunedParameters:
    """Parameters for ``--params``: a Table 3 set name (ft, ga, ce, sa) or a YAML/JSON file.

    The file holds the six names at the top level or under ``best_params`` (the summary that
    ``twin optimize`` writes).
    """
    if spec.lower() in paper.TABLE3:
        return paper.TABLE3[spec.lower()]
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(
            f"--params {spec}: neither a set of Table 3 {sorted(paper.TABLE3)} nor a file"
        )
    data = load_yaml(path)
    if isinstance(data, dict) and "best_params" in data:
        return tuned_from_mapping(data["best_params"], f"{path}: best_params")
    return tuned_from_mapping(data, str(path))
