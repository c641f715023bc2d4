"""Measured circular tests: read, replay on the twin, and diagnose the gap axis by axis; virtual
X-Y machines that make such tests with a known answer.

A measured circular test is a CSV of ``t`` [s], ``x_ref``, ``y_ref`` [m] (the CNC's
references), ``x``, ``y`` [m] (the measured positions: scales or a grid encoder), and optionally
``current_x``, ``current_y`` [A] (the drives' current commands). Coordinates may have any
origin: the test's nominal centre and radius are those of the least-squares circle of the
references.

The twin replays the references on every axis together; the test is evaluated (ISO 230-4) on
the measured and on the twin's path; the gap at each quadrant transition is the difference of
the two reversal spikes. Each axis is then diagnosed with :func:`twin_cosim.gap.diagnosis.diagnose`
as a single-axis run (its reference, its measured position and current): the axis whose
diagnosis accepts an effect, with the largest held-out reduction, is where the gap lies.

**The gap diagnosis** of a measured circular test, axis by axis, and virtual X-Y machines.
:func:`diagnose_circle` replays the test on the twin (:func:`replay_circle`) and diagnoses each axis
that has a current column as a single-axis run (:func:`twin_cosim.gap.diagnosis.diagnose`, a time
split of the run into training and held-out halves). The verdict names the axis whose diagnosis
accepts an effect with the largest held-out reduction, that effect, and the quadrant transition of
that axis where the measured and the twin's reversal spikes differ the most.

:func:`synthesize_motion` makes a measured test whose answer is known: a planned motion (the
circle's, :func:`~twin_cosim.contour.circle.circle_motion`; a part program's) run on a virtual
machine, the twin with effects switched on in its axes' plants
(:func:`twin_cosim.gap.synth.synthesize` per axis; the axes do not interact), calibration error
and measurement noise, its geometric errors (``twin synth MACHINE``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from twin_cosim.contour.ballbar import ballbar_figures, cyclic_periods
from twin_cosim.contour.circle import (
    HYSTERESIS_STEP_DEG,
    SPIKE_LEAD_DEG,
    SPIKE_WINDOW_DEG,
    CircleResult,
    evaluate_circle,
    least_squares_circle,
    on_grid,
)
from twin_cosim.contour.interpolation import PlannedMotion
from twin_cosim.contour.machine_run import MachinePlants, MachineRecord, axis_grids, run_machine
from twin_cosim.contour.path import Arc
from twin_cosim.gap.diagnosis import Diagnosis, diagnose
from twin_cosim.gap.report.pages import summary
from twin_cosim.gap.settings import settings_from
from twin_cosim.gap.synth import EffectSpec, synthesize
from twin_cosim.measured import MeasuredDataError, MeasuredRun, check_time
from twin_cosim.reference import interpolate
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario.machine import MachineScenario

COLUMNS = {"X": ("x_ref", "x", "current_x"), "Y": ("y_ref", "y", "current_y")}
CONSTANT_FEED = 0.99  # share of the top path speed above which the feed counts as constant


@dataclass(frozen=True)
class MeasuredCircle:
    """A measured circular test, centred on its references' least-squares circle.

    Attributes
    ----------
    source : str
        The file.
    t : numpy.ndarray
        Sample times, s (regular).
    reference, actual : dict
        Axis name -> reference and measured position, m, about the nominal centre.
    current : dict
        Axis name -> current command, A (empty without currents).
    centre : tuple
        The nominal centre in the file's coordinates, m.
    radius : float
        Nominal radius, m.
    direction : str
        ``cw`` or ``ccw``.
    """

    source: str
    t: np.ndarray
    reference: dict[str, np.ndarray]
    actual: dict[str, np.ndarray]
    current: dict[str, np.ndarray]
    centre: tuple[float, float]
    radius: float
    direction: str

    @property
    def period(self) -> float:
        """Sample period, s."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    def axis_run(self, name: str) -> MeasuredRun:
        """One axis as a measured single-axis run (file coordinates), for the diagnosis."""
        if name not in self.current:
            raise MeasuredDataError(
                f"{self.source}: the diagnosis of axis {name} needs its current column "
                f"{COLUMNS[name][2]!r}"
            )
        offset = self.centre[0 if name == "X" else 1]
        return MeasuredRun.from_signals(
            f"{self.source} (axis {name})",
            {
                "t": self.t,
                "x_ref": self.reference[name] + offset,
                "x": self.actual[name] + offset,
                "current": self.current[name],
            },
        )


def read_measured_circle(path: Path | str) -> MeasuredCircle:
    """Read and check a measured circular test (see the module docstring).

    Raises
    ------
    MeasuredDataError
        Naming the file and the column on a missing column, a non-numeric or non-finite value,
        irregular time or references that do not go round a circle.
    """
    path = Path(path)
    try:
        table = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as CSV: {exc}") from exc
    required = ("t", "x_ref", "y_ref", "x", "y")
    missing = [c for c in required if c not in table.columns]
    if missing:
        raise MeasuredDataError(
            f"{path}: missing column(s) {missing}; expected t [s], x_ref, y_ref, x, y [m] "
            f"(optional current_x, current_y [A]), found {list(table.columns)}"
        )
    names = required + tuple(c for c in ("current_x", "current_y") if c in table.columns)
    values = {}
    for name in names:
        column = pd.to_numeric(table[name], errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(column))
        if len(bad):
            raise MeasuredDataError(
                f"{path}: column {name!r}: missing, non-numeric or non-finite value at file line "
                f"{bad[0] + 2}"
            )
        values[name] = column
    t = values["t"]
    check_time(MeasuredRun.from_signals(str(path), {"t": t, "x_ref": values["x_ref"]}))
    cx, cy, radius = least_squares_circle(values["x_ref"], values["y_ref"])
    turn = np.unwrap(np.arctan2(values["y_ref"] - cy, values["x_ref"] - cx))
    if not radius > 0 or abs(turn[-1] - turn[0]) < 2 * math.pi * 0.99:
        raise MeasuredDataError(
            f"{path}: columns 'x_ref', 'y_ref' do not go once round a circle (a circular test "
            "needs 360 degrees of reference)"
        )
    return MeasuredCircle(
        source=str(path),
        t=t,
        reference={"X": values["x_ref"] - cx, "Y": values["y_ref"] - cy},
        actual={"X": values["x"] - cx, "Y": values["y"] - cy},
        current={
            axis: values[column] for axis, (_, _, column) in COLUMNS.items() if column in values
        },
        centre=(cx, cy),
        radius=radius,
        direction="ccw" if turn[-1] > turn[0] else "cw",
    )


def data_rows(measured: MeasuredCircle) -> np.ndarray:
    """The samples of the data circle: 360 degrees from the first at constant feed."""
    x, y = measured.reference["X"], measured.reference["Y"]
    speed = np.hypot(np.gradient(x, measured.t), np.gradient(y, measured.t))
    steady = np.flatnonzero(speed >= CONSTANT_FEED * speed.max())
    angle = np.unwrap(np.arctan2(y, x))
    travelled = np.abs(angle - angle[steady[0]])
    rows = np.zeros(len(x), dtype=bool)
    rows[steady[0] :] = travelled[steady[0] :] < 2 * math.pi
    return rows & (speed >= CONSTANT_FEED * speed.max())


def _motion(machine: MachineScenario, measured: MeasuredCircle) -> PlannedMotion:
    """The measured references as the machine's motion (a Z axis stands at 0)."""
    samples = np.column_stack(
        [measured.reference.get(name, np.zeros(len(measured.t))) for name in machine.axis_names]
    )
    circle = Arc((0.0, 0.0), measured.radius, 0.0, 2 * math.pi)
    return PlannedMotion(
        machine.axis_names, measured.period, samples, (circle,), float(measured.t[-1]), ()
    )


def _on_data(contour: RunRecord, rows: np.ndarray, t: np.ndarray) -> RunRecord:
    """The contour record's samples at the measured data circle's times."""
    times = t[rows]
    return RunRecord.from_columns(
        {
            "t": times,
            "x": np.interp(times, contour["t"], contour["x"]),
            "y": np.interp(times, contour["t"], contour["y"]),
        },
        contour.units,
    )


@dataclass(frozen=True)
class CircleReplay:
    """The twin's replay of a measured circular test and the comparison of the two.

    Attributes
    ----------
    measured : MeasuredCircle
        The test.
    record : MachineRecord
        The twin's run on the measured references.
    on_machine, on_twin : CircleResult
        ISO 230-4 evaluation of the measured path and of the twin's.
    """

    measured: MeasuredCircle
    record: MachineRecord
    on_machine: CircleResult
    on_twin: CircleResult

    def transition_gaps(self) -> list[dict[str, Any]]:
        """Per quadrant transition: its axis, the measured and the twin's spike (um, ms) and
        ``gap_um``, the largest radial difference of the two paths (um) in the transition's
        window (where its spike is looked for)."""
        sign = 1.0 if self.measured.direction == "ccw" else -1.0
        grid = np.arange(0.0, 360.0, HYSTERESIS_STEP_DEG)
        difference = on_grid(self.on_machine, grid) - on_grid(self.on_twin, grid)
        gaps = []
        for m, s in zip(self.on_machine.spikes, self.on_twin.spikes, strict=True):
            travelled = (sign * (grid - m.angle_deg) + 180.0) % 360.0 - 180.0
            window = (travelled >= -SPIKE_LEAD_DEG) & (travelled <= SPIKE_WINDOW_DEG)
            gaps.append(
                {
                    "angle_deg": m.angle_deg,
                    "axis": m.axis,
                    "machine_height_um": m.height_um,
                    "twin_height_um": s.height_um,
                    "machine_width_ms": m.width_ms,
                    "twin_width_ms": s.width_ms,
                    "gap_um": float(np.max(np.abs(difference[window]))),
                }
            )
        return gaps

    def axis_gaps(self) -> dict[str, float]:
        """RMS of measured minus twin position per axis, um."""
        gaps = {}
        for name, axis in self.record.axes.items():
            twin = np.interp(self.measured.t, axis["t"], axis["x"])
            gaps[name] = float(np.sqrt(np.mean((self.measured.actual[name] - twin) ** 2)) * 1e6)
        return gaps


def replay_circle(
    machine: MachineScenario, measured: MeasuredCircle, plants: MachinePlants, fast: bool = True
) -> CircleReplay:
    """Replay a measured test on the twin and evaluate both paths."""
    motion = _motion(machine, measured)
    axis_grids(machine, motion)  # the size check, before the run
    record = run_machine(machine, motion, plants, fast)
    rows = data_rows(measured)
    speed = float(
        np.median(
            np.hypot(
                np.gradient(measured.reference["X"], measured.t),
                np.gradient(measured.reference["Y"], measured.t),
            )[rows]
        )
    )
    machine_data = RunRecord.from_columns(
        {"t": measured.t[rows], "x": measured.actual["X"][rows], "y": measured.actual["Y"][rows]},
        {"t": "s", "x": "m", "y": "m"},
    )
    on_machine = evaluate_circle(machine_data, measured.radius, measured.direction, speed)
    twin_data = _on_data(record.contour, rows, measured.t)
    on_twin = evaluate_circle(twin_data, measured.radius, measured.direction, speed)
    return CircleReplay(measured, record, on_machine, on_twin)


def diagnose_circle(
    machine: MachineScenario,
    measured: MeasuredCircle,
    fast: bool = True,
    workers: int | None = 1,
    max_effects: int | None = 1,
) -> dict[str, Any]:
    """Replay and diagnose a measured circular test.

    Parameters
    ----------
    machine
        The machine the test was run on (its twin).
    measured
        The test.
    fast
        Compiled replay (default) or the fmpy reference path.
    workers
        Replay processes of each axis' diagnosis (1: in this process).
    max_effects
        Most effects accepted per axis.

    Returns
    -------
    dict
        ``machine`` and ``twin`` (ISO 230-4 figures of each path), ``ballbar`` (the ballbar's
        diagnostics of each, :func:`~twin_cosim.contour.ballbar.ballbar_figures`),
        ``transitions`` (per quadrant transition: axis, measured and twin spike, gap in um),
        ``axis_gap_rms_um``, ``axes`` (each diagnosed axis: verdict, accepted effects, held-out
        reduction), ``verdict`` (``axis``, ``effect``, ``transition_deg``, ``text``) and
        ``paths`` (the two :class:`~twin_cosim.contour.circle.CircleResult`, for plots; not
        JSON).
    """
    with MachinePlants(machine) as plants:
        replay = replay_circle(machine, measured, plants, fast)
    transitions = replay.transition_gaps()
    found: dict[str, Any] = {}
    diagnoses: dict[str, Diagnosis] = {}
    for name in machine.axis_names:
        if name not in measured.current:
            continue
        run = measured.axis_run(name)
        grid = interpolate(run.x_ref, measured.period, machine.axes[0].settings.position_period)
        scenario = machine.axis_scenario(name, grid)
        settings = settings_from(scenario, max_effects=max_effects)
        diagnosis = diagnoses[name] = diagnose(scenario, [run], [], None, settings, workers=workers)
        found[name] = {
            "verdict": diagnosis.verdict,
            "significant": diagnosis.significant,
            "accepted": diagnosis.accepted,
            "steps": summary(diagnosis)["steps"],
        }
    return {
        "source": measured.source,
        "radius_mm": measured.radius * 1e3,
        "direction": measured.direction,
        "machine": replay.on_machine.summary(),
        "twin": replay.on_twin.summary(),
        "ballbar": {
            name: ballbar_figures([path], measured.radius, cyclic_periods(machine))
            for name, path in (("machine", replay.on_machine), ("twin", replay.on_twin))
        },
        "transitions": transitions,
        "axis_gap_rms_um": replay.axis_gaps(),
        "axes": found,
        "verdict": _verdict(diagnoses, transitions),
        "paths": {"machine": replay.on_machine, "twin": replay.on_twin},
    }


def _reduction(diagnosis: Diagnosis) -> float:
    """Held-out reduction of the position gap by the axis' first accepted effect (0 when none)."""
    if not diagnosis.accepted or not diagnosis.steps:
        return 0.0
    first = diagnosis.steps[0]
    assert first.best is not None
    before, after = first.position_rms_um, first.best.judgement.position_rms_um
    return (before - after) / before if before > 0 else 0.0


def _verdict(diagnoses: dict[str, Diagnosis], transitions: list[dict[str, Any]]) -> dict[str, Any]:
    """The axis, effect and quadrant transition where the gap lies, in numbers and words."""
    candidates = [name for name, d in diagnoses.items() if d.accepted]
    if not candidates:
        return {
            "axis": None,
            "effect": None,
            "transition_deg": None,
            "text": "no axis' diagnosis accepts an effect: the twin explains the test "
            "within its noise and calibration floors",
        }
    axis = max(candidates, key=lambda name: _reduction(diagnoses[name]))
    effect = diagnoses[axis].selection.accepted[0][0]
    own = [t for t in transitions if t["axis"] == axis]
    worst = max(own, key=lambda t: abs(t["gap_um"]))
    return {
        "axis": axis,
        "effect": effect,
        "transition_deg": worst["angle_deg"],
        "text": f"the gap lies in axis {axis}: {effect} (held-out gap "
        f"{_reduction(diagnoses[axis]):.0%} smaller with it); largest at the "
        f"{worst['angle_deg']:g} degree transition, where {axis} reverses: the paths differ by "
        f"up to {worst['gap_um']:.2f} um (spike: measured {worst['machine_height_um']:+.2f} um, "
        f"twin {worst['twin_height_um']:+.2f} um)",
    }


def synthesize_motion(
    machine: MachineScenario,
    motion: PlannedMotion,
    effects: dict[str, list[EffectSpec]],
    perturb: float = 0.0,
    seed: int = 0,
    noise_position: float = 20e-9,
    noise_current: float = 5e-3,
    decimate: int = 4,
) -> RunRecord:
    """A measured run of a virtual machine following a planned motion (a circle, a program).

    Each axis runs its reference with the effects of ``effects`` switched on in its plant
    (:func:`twin_cosim.gap.synth.synthesize`; the axes do not interact), calibration error and
    measurement noise; the measured X and Y are the tool point (the machine's geometric errors
    applied), as a ballbar or a grid encoder reads it.

    Parameters
    ----------
    machine
        The nominal machine (its geometry is the virtual machine's).
    motion
        The per-axis references.
    effects
        Axis name -> effects switched on in that axis' plant.
    perturb
        Largest relative calibration error of each axis' calibrated parameters.
    seed
        Seed of calibration errors and noise (each axis its own stream).
    noise_position, noise_current
        Standard deviations of the white measurement noise, m and A.
    decimate
        Keep every n-th position-loop sample (4: 1 ms).

    Returns
    -------
    RunRecord
        ``t`` (s), ``<axis>_ref`` and ``<axis>`` (m) of every axis, ``current_<axis>`` (A).
    """
    grids = axis_grids(machine, motion)
    columns: dict[str, np.ndarray] = {}
    for k, name in enumerate(machine.axis_names):
        scenario = machine.axis_scenario(name, grids[name])
        run = synthesize(
            scenario,
            effects.get(name, []),
            perturb,
            seed * 10 + k,
            noise_position=noise_position,
            noise_current=noise_current,
        ).run
        lower = name.lower()
        columns["t"] = run["t"]
        columns[f"{lower}_ref"] = run["x_ref"]
        columns[lower] = run["x"]
        columns[f"current_{lower}"] = run["current"]
    columns["x"], columns["y"] = machine.geometry.tool_point(columns["x"], columns["y"])
    lower = [name.lower() for name in machine.axis_names]
    order = ["t"] + [f"{a}_ref" for a in lower] + lower + [f"current_{a}" for a in lower]
    units = {name: "A" if name.startswith("current") else "m" for name in order} | {"t": "s"}
    table = RunRecord.from_columns({name: columns[name] for name in order}, units)
    return table.rows(slice(None, None, decimate))
