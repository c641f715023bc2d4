"""The ``reference`` section of a scenario: segments, a CSV of samples, or a measured run.

Layout::

    reference:
      sample_period: 0.004                   # s
      start_position: 0.0                    # m
      segments:                              # or  csv: samples.csv  (columns t [s], x_ref [m])
        - dwell: 0.5                         # s
        - move: {to: 0.02, velocity: 0.02, acceleration: 0.5}   # m, m/s, m/s^2
        - oscillation: {amplitude: 0.01, frequency: 1.0, cycles: 2}  # m, Hz, 1
        - ramp: {velocity: 0.01, acceleration: 0.1, duration: 1.0}   # m/s, m/s^2, s

A measured reference (``reference.measured``, a file relative to the scenario) is looked up first
by its file name in the data folder given by ``--data DIR`` or the environment variable
``TWIN_COSIM_DATA``; ``reference.data_source`` says what the data is and where to get it, for the
error when it is missing. ``reference.disturbance`` declares the signal convention of a measured
run's disturbance (which variable, its gain, where it enters the loop). The size of a run is
checked before anything is allocated (``run.max_samples``).

**Open loop** (``reference.drive: SIGNAL``, with a measured reference only): the plant is driven
by that signal of each measured run instead of the cascade, e.g. a torque bench's
``input_torque`` (or its ``measured_torque``, if the scenario says so). A signal in N.m becomes
the plant's current command through the drive's torque constant
(``controller.settings.torque_constant``), one in A is the command itself; it is held over each
sample of the run. The run's measured motion is the reference the twin is compared with: its
position ``x`` (a rotor's ``motor_angle`` times ``controller.settings.travel_per_rad``) and its
motor speed. Every run given to a command follows its own drive signal
(:func:`twin_cosim.scenario.for_measured_run`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.controller import ControllerSettings
from twin_cosim.environment import DATA_ENV
from twin_cosim.measured import MeasuredDataError, MeasuredRun, read_measured
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
from twin_cosim.schema import Checker, ScenarioError

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


def _segment(check: Checker, item: Any, key: str):
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
class ReferenceSection:
    """A checked ``reference`` section.

    Attributes
    ----------
    grid : ReferenceGrid
        The reference on the position-loop grid.
    start : float
        Reference position at t = 0, m.
    measured : Path or None
        The measured run the reference was taken from.
    plant_start : float or None
        The measured carriage position at t = 0 (m), where the plant starts.
    disturbance : numpy.ndarray or None
        Disturbance input per position-loop sample (N.m, or N on a linear axis).
    disturbance_spec : dict
        The signal convention of ``reference.disturbance`` (empty when absent).
    command_disturbance : numpy.ndarray or None
        Signal added to the controller's output per position-loop sample (the command's unit).
    drive : str or None
        Open loop: the measured run's signal that drives the plant (``reference.drive``).
    open_loop : numpy.ndarray or None
        Open loop: the plant's current command per position-loop sample, A.
    """

    grid: ReferenceGrid
    start: float
    measured: Path | None = None
    plant_start: float | None = None
    disturbance: np.ndarray | None = None
    disturbance_spec: dict[str, Any] = field(default_factory=dict)
    command_disturbance: np.ndarray | None = None
    drive: str | None = None
    open_loop: np.ndarray | None = None


# Where a measured run's disturbance signal enters the loop (reference.disturbance.enters).
DISTURBANCE_ENTRIES = ("disturbance_input", "command")


def run_disturbance(
    run: MeasuredRun, spec: dict[str, Any], grid: ReferenceGrid
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(disturbance input, command disturbance) of a run: ``gain`` x its ``variable`` on the
    grid, at the plant's disturbance input (N.m, or N) or added to the command (its unit).

    A run without that variable (e.g. the EMPS estimation run, which has no pulses) has none.
    """
    values = run.record.get(spec["variable"]) if spec else None
    if not isinstance(values, np.ndarray):
        return None, None
    signal = spec["gain"] * np.interp(grid.time, run.t, values)
    return (signal, None) if spec["enters"] == "disturbance_input" else (None, signal)


def _disturbance_spec(check: Checker, data: Any) -> dict[str, Any]:
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


# Units an open-loop drive signal may have, and the command it becomes (by the drive's torque
# constant K_t, N.m/A): a torque divided by K_t, a current as it is.
DRIVE_UNITS = ("N.m", "A")


def open_loop_of(
    run: MeasuredRun, drive: str, travel_per_rad: float, torque_constant: float, period: float
) -> tuple[MeasuredRun, ReferenceGrid, np.ndarray]:
    """An open-loop run driven by its signal ``drive``: the run (its measured motion as its
    reference, :meth:`~twin_cosim.measured.MeasuredRun.open_loop`), that reference on the
    position-loop grid of ``period`` (s), and the plant's current command per grid sample (A):
    the signal held from each sample to the next, a torque (N.m) divided by ``torque_constant``
    (N.m/A).

    Raises
    ------
    MeasuredDataError
        When the run lacks the signal, a position or the motor speed, or the signal is neither a
        torque nor a current.
    ReferenceError
        When the run's period does not fit the grid's.
    """
    run = run.open_loop(drive, travel_per_rad)
    unit = run.record.units.get(drive, "")
    if unit not in DRIVE_UNITS:
        raise MeasuredDataError(
            f"{run.source}: the drive signal {drive!r} is in {unit or 'no unit'}; an open-loop "
            f"drive is a torque or a current ({' or '.join(DRIVE_UNITS)})"
        )
    grid = interpolate(run.x_ref, run.period, period)
    held = np.clip(np.searchsorted(run.t, grid.time + 1e-9 * period, side="right") - 1, 0, None)
    command = run.record[drive][held]
    return run, grid, command / torque_constant if unit == "N.m" else command.copy()


def data_dir() -> Path | None:
    """The data folder given by ``--data`` or the environment variable ``TWIN_COSIM_DATA``."""
    value = os.environ.get(DATA_ENV)
    return Path(value) if value else None


def _measured_path(check: Checker, data: dict[str, Any]) -> Path:
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
    check: Checker, duration: float, position_period: float, max_samples: int, what: str
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
    check: Checker,
    data: dict[str, Any],
    settings: ControllerSettings,
    max_samples: int,
    columns: dict[str, str],
) -> ReferenceSection:
    """The reference (and disturbance, or open-loop drive) of a measured run file."""
    path = _measured_path(check, data)
    drive = data.get("drive")
    if drive is not None and not isinstance(drive, str):
        raise check.fail("reference.drive", "the name of a signal of the measured run", drive)
    try:
        run = read_measured(path, columns, open_loop=drive is not None)
        if abs(run.t[0]) > 0.5 * run.period:
            raise check.fail(
                "reference.measured", "a run whose time starts at 0 s", float(run.t[0])
            )
        _check_size(
            check, float(run.t[-1]), settings.position_period, max_samples, "reference.measured"
        )
        command = None
        if drive is None:
            grid = interpolate(run.x_ref, run.period, settings.position_period)
        else:
            run, grid, command = open_loop_of(
                run,
                drive,
                settings.travel_per_rad,
                settings.torque_constant,
                settings.position_period,
            )
    except MeasuredDataError as exc:
        raise ScenarioError(f"{check.source}: reference.measured: {exc}") from exc
    except ReferenceError as exc:
        raise ScenarioError(f"{check.source}: reference: {exc}") from exc
    spec = _disturbance_spec(check, data.get("disturbance"))
    at_input, at_command = run_disturbance(run, spec, grid)
    return ReferenceSection(
        grid,
        float(run.x_ref[0]),
        path,
        float(run.x[0]),
        at_input,
        spec,
        at_command,
        drive,
        command,
    )


def reference_section(
    check: Checker,
    data: Any,
    settings: ControllerSettings,
    max_samples: int,
    columns: dict[str, str],
) -> ReferenceSection:
    """The checked ``reference`` section, its measured file read with the column map
    ``columns`` (signal -> the file's column) and, in open loop, with the drive facts of
    ``settings``."""
    position_period = settings.position_period
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
            "drive",
        },
    )
    sources = [key for key in ("segments", "csv", "measured") if key in data]
    if len(sources) != 1:
        raise check.fail("reference", "exactly one of 'segments', 'csv' or 'measured'")
    if "measured" in data:
        return _from_measured(check, data, settings, max_samples, columns)
    for key in ("disturbance", "data_source", "drive"):
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
        return ReferenceSection(interpolate(samples, sample_period, position_period), start)
    except ReferenceError as exc:
        raise ScenarioError(f"{check.source}: reference: {exc}") from exc
