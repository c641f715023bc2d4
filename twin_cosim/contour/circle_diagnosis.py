"""The gap diagnosis of a measured circular test, axis by axis, and virtual X-Y machines.

:func:`diagnose_circle` replays the test on the twin (:mod:`twin_cosim.contour.measured_circle`)
and diagnoses each axis that has a current column as a single-axis run
(:func:`twin_cosim.gap.diagnosis.diagnose`, a time split of the run into training and held-out
halves). The verdict names the axis whose diagnosis accepts an effect with the largest
held-out reduction, that effect, and the quadrant transition of that axis where the measured
and the twin's reversal spikes differ the most.

:func:`synthesize_motion` makes a measured test whose answer is known: a planned motion (the
circle's, :func:`~twin_cosim.contour.circle.circle_motion`; a part program's) run on a virtual
machine, the twin with effects switched on in its axes' plants
(:func:`twin_cosim.gap.synth.synthesize` per axis; the axes do not interact), calibration error
and measurement noise, its geometric errors (``twin synth MACHINE``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from twin_cosim.contour.ballbar import ballbar_figures, cyclic_periods
from twin_cosim.contour.interpolation import PlannedMotion
from twin_cosim.contour.machine_run import MachinePlants, axis_grids
from twin_cosim.contour.measured_circle import MeasuredCircle, replay_circle
from twin_cosim.gap.diagnosis import Diagnosis, diagnose
from twin_cosim.gap.report.pages import summary
from twin_cosim.gap.settings import settings_from
from twin_cosim.gap.synth import EffectSpec, synthesize
from twin_cosim.reference import interpolate
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario.machine import MachineScenario


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
