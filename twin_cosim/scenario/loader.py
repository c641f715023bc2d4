"""Loading a scenario file: every section read and checked once, resolved into a Scenario; the
scenarios shipped with the package, found by name (``reference1``) as well as by path.

Layout (every section but ``reference`` is optional)::

    name: reference1
    description: free text
    plant: {...}                             # twin_cosim.scenario.plant_parameters
    controller:
      parameters: {Kp_pos: 66.667, ...}      # the six tuned parameters, or the name of a set of
                                             # the paper's Table 3 (ft, ga, ce, sa); default: ft
      settings: {current_limit: 20.0, ...}   # twin_cosim.scenario.controller_section: fixed
                                             # settings and the current-setpoint filters
    reference: {...}                         # twin_cosim.scenario.reference_section
    run:
      metrics_window: [0.0, null]            # s; null: to the end
      max_samples: 2400000                   # position-loop samples a run may have at most
    optimize: {...}                          # see twin_cosim.optimize.config
    diagnose: {...}                          # see twin_cosim.gap.settings.settings_from
    measured_columns: {x: ActPos, t: Time}   # the measured files' column names, per signal
                                             # (twin_cosim.measured; --columns wins)

Every error names the file and the key path, and says what was expected. ``name`` (used as the
default output folder) must be a plain file name. A scenario may name an FMU, which is native
code that runs in this process: use scenario files from trusted sources only.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from twin_cosim.measured import SIGNALS
from twin_cosim.scenario.controller_section import controller_section
from twin_cosim.scenario.plant_parameters import (
    check_friction_below_peak_torque,
    plant_section,
    with_plant_parameters,
)
from twin_cosim.scenario.reference_section import reference_section
from twin_cosim.scenario.resolved import Scenario
from twin_cosim.schema import Checker, ScenarioError, load_yaml

TOP_KEYS = {
    "name",
    "description",
    "plant",
    "controller",
    "reference",
    "run",
    "optimize",
    "diagnose",
    "measured_columns",
}
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")
MAX_SAMPLES = 2_400_000  # position-loop samples of a run: 10 min at 250 us
_PACKAGE = Path(__file__).resolve().parents[1]


def load_scenario(path: Path | str) -> Scenario:
    """Load and check a scenario file (a path or the name of a shipped scenario).

    Raises
    ------
    ScenarioError
        On malformed YAML, unknown keys, wrong types, non-finite or out-of-range values.
    """
    check, data, name = read_top_level(path, TOP_KEYS, "reference", "a reference section")
    source = Path(check.source)
    plant = plant_section(check, data.get("plant"))
    tuned, settings = controller_section(check, plant, data.get("controller"))
    check_friction_below_peak_torque(check, plant, settings.current_limit)
    run = check.mapping(data.get("run"), "run", {"metrics_window", "max_samples"})
    max_samples = check.number(run.get("max_samples", MAX_SAMPLES), "run.max_samples", minimum=2)
    columns = measured_columns(check, data.get("measured_columns"))
    chosen = reference_section(check, data["reference"], settings, int(max_samples), columns)
    parameters = dict(plant.parameters)
    parameters.setdefault(
        "load_position_start", chosen.start if chosen.plant_start is None else chosen.plant_start
    )
    return Scenario(
        name=name,
        description=str(data.get("description", "")),
        source=source,
        fmu=plant.fmu,
        plant_parameters=parameters,
        tuned=tuned,
        settings=settings,
        reference=chosen.grid,
        metrics_window=_metrics_window(check, run, chosen.grid.duration),
        optimize=check.mapping(data.get("optimize"), "optimize"),
        diagnose=check.mapping(data.get("diagnose"), "diagnose"),
        measured=chosen.measured,
        disturbance=chosen.disturbance,
        disturbance_spec=chosen.disturbance_spec,
        command_disturbance=chosen.command_disturbance,
        disturbance_in_record=bool(chosen.disturbance_spec.get("in_recorded_command", False)),
        model=plant.model,
        plant_parameters_file=plant.parameters_file,
        measured_columns=columns,
        drive=chosen.drive,
        open_loop=chosen.open_loop,
    )


def measured_columns(check: Checker, data: Any) -> dict[str, str]:
    """The ``measured_columns`` map: a signal of a measured run -> the files' column name."""
    columns = check.mapping(data, "measured_columns", set(SIGNALS))
    for signal, name in columns.items():
        if not isinstance(name, str) or not name.strip():
            raise check.fail(f"measured_columns.{signal}", "the name of a column", name)
    return {signal: name.strip() for signal, name in columns.items()}


def read_top_level(
    path: Path | str, keys: set[str], required: str, what: str
) -> tuple[Checker, dict[str, Any], str]:
    """A scenario file's checker, its top-level mapping (only ``keys``; ``required`` present,
    ``what`` saying what it must be) and its name (``name``, checked to be a plain file name;
    else the file's stem): the start that every scenario file shares."""
    source = find_scenario(path)
    check = Checker(source)
    data = check.mapping(load_yaml(source), "(top level)", keys)
    if required not in data:
        raise check.fail(required, what)
    name = str(data.get("name", source.stem))
    if "name" in data and not NAME_PATTERN.fullmatch(name):
        raise check.fail(
            "name",
            "a plain file name (letters, digits, '.', '_', '-'; at most 100; no folders), "
            "used as the default output folder",
            name,
        )
    return check, data, name


def _metrics_window(
    check: Checker, run: dict[str, Any], duration: float
) -> tuple[float, float | None]:
    """``run.metrics_window`` checked against the reference's duration (s)."""
    window = run.get("metrics_window", [0.0, None])
    if not isinstance(window, list) or len(window) != 2:
        raise check.fail("run.metrics_window", "[t0, tF] in s (tF may be null)", window)
    t0 = check.number(window[0], "run.metrics_window[0]", minimum=0.0)
    t_end = None if window[1] is None else check.number(window[1], "run.metrics_window[1]")
    if t_end is not None and not t0 < t_end <= duration + 1e-9:
        raise check.fail("run.metrics_window", f"0 <= t0 < tF <= {duration:g} s", window)
    return t0, t_end


def resolve_scenario(
    path: Path | str, plant_parameters: Path | str | None = None, fmu: Path | str | None = None
) -> Scenario:
    """The scenario of a file (or shipped name), with a plant parameter file applied.

    Parameters
    ----------
    path
        Scenario YAML file, or the name of a shipped scenario.
    plant_parameters
        Plant parameter file whose values win over the scenario's; none: the scenario's own.
    fmu
        The plant actually used (``--plant``), whose model the parameter file must be of;
        none: the scenario's.

    Raises
    ------
    ScenarioError
        On a malformed scenario file.
    PlantParametersError
        On a malformed plant parameter file, or one of another model than the plant's.
    """
    return with_plant_parameters(load_scenario(path), plant_parameters, fmu)


def packaged_scenarios_dir() -> Path:
    """The shipped scenarios: ``twin_cosim/scenarios`` of a wheel, else ``scenarios/``."""
    packaged = _PACKAGE / "scenarios"
    return packaged if packaged.is_dir() else _PACKAGE.parent / "scenarios"


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
