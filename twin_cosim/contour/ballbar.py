"""The ballbar's diagnostics of a circular test: each machine error by its signature on the
circle.

A ballbar (Renishaw QC20's diagnostics) reads the radial deviation r(theta) of the tool's path
from the nominal circle and fits the signature of each error to it. Here all signatures are
fitted at once, in least squares, to the data circle of one or both directions, the samples
near the quadrant transitions (where the reversal spikes are, :mod:`~twin_cosim.contour.circle`)
left out. With the circle's radius R, its direction s (+1 counter-clockwise, -1 clockwise), the
path speed v and c = cos theta, n = sin theta:

=====================  ==========================================  ===========================
error                  signature in r(theta)                       reported as
=====================  ==========================================  ===========================
centre offset          x0 c + y0 n (per direction)                 ``centre_offset_um``
                                                                   (X, Y), um: mean of the
                                                                   directions
scale mismatch         R (s_X - s_Y)/2 cos 2 theta                 ``scale_mismatch_um_per_m``
                                                                   = (s_X - s_Y) 1e6: X minus Y
squareness             -R alpha/2 sin 2 theta (alpha: the angle    ``squareness_um_per_m``
                       between +X and +Y minus 90 deg)             = alpha 1e6: + when obtuse
servo mismatch         -s v (T_Y - T_X)/2 sin 2 theta: flips with  ``servo_mismatch_ms``
                       the direction (T: an axis' lag)             = T_Y - T_X: + when Y lags
straightness           X: -S_X/4 (n + sin 3 theta);                ``straightness_um`` (X, Y):
                       Y: -S_Y/4 (c - cos 3 theta)                 the bow S over the circle's
                                                                   diameter, + toward + of the
                                                                   other axis
backlash               at each reversal of an axis, a step b of    ``backlash_um`` (X, Y:
                       the path along it, outward in the           ``positive`` at the axis'
                       direction of travel: b/2 sign(travelled     positive end, 0 deg for X,
                       since the reversal) |c| (X) or |n| (Y) on   90 for Y; ``negative`` at
                       that half of the circle                     180 and 270 deg), um: +
                                                                   lost motion, - overshoot
lateral play           the tool shifts across an axis by p as      ``lateral_play_um`` (X, Y),
                       that axis reverses: X: -s p/2 |n|,          um (both directions needed)
                       Y: s p/2 |c|
cyclic error           A sin(2 pi x / P) along X: its c times      ``cyclic_error_um`` (X, Y):
                       sin and cos of 2 pi R c / P (Y: n, n)       the amplitude A, um, at the
                                                                   period ``cyclic_period_mm``
=====================  ==========================================  ===========================

The samples the fitted signatures leave far off (a ringing that outlasts a spike's window, a
stick-slip: no error of the table) are left out and the fit made again, up to
:data:`ROBUST_ROUNDS` times.

The reversal spikes (the transient at each quadrant transition) are the circle's own figures
(:class:`~twin_cosim.contour.circle.Spike`); ``reversal_spikes_um`` lists them per axis and
end, the mean of the directions. With one direction the ellipse at 45 degrees cannot be split
into squareness and servo mismatch: it is reported as squareness, ``servo_mismatch_ms`` and
``lateral_play_um`` are null (a note says so).

A servo engineer's reading on this twin: the axes close their position loops on their scales,
so a plant's backlash (drive2mass ``backlash``) shows as a reversal spike (the carriage stands
while the motor crosses the gap) and as a step only as far as the loop leaves one after the
spike (docs/contouring.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin_cosim.contour.circle import (
    REVERSING_AXIS,
    SPIKE_LEAD_DEG,
    SPIKE_WINDOW_DEG,
    TRANSITIONS_DEG,
    CircleResult,
    travelled_since,
)
from twin_cosim.scenario.machine import MachineScenario

UM = 1e-6  # m per um
OUTLIER_SPREAD = 4.0  # samples beyond this many robust standard deviations are left out
OUTLIER_FLOOR = 0.05e-6  # m: never closer than this
ROBUST_ROUNDS = 4
ENDS = {0.0: ("X", "positive"), 180.0: ("X", "negative"), 90.0: ("Y", "positive")}
ENDS[270.0] = ("Y", "negative")


@dataclass(frozen=True)
class Signature:
    """One column of the fit: its name and its values on the samples of every direction."""

    name: str
    values: np.ndarray


def _step(theta: np.ndarray, sign: float, transition: float) -> np.ndarray:
    """The backlash step at ``transition`` (deg): +-1/2 |c| or |n| on the half of the circle
    around it, - before and + after it in the direction of travel."""
    travelled = travelled_since(np.degrees(theta) % 360.0, transition, sign)
    near = np.abs(travelled) < 90.0
    along = np.abs(np.cos(theta)) if REVERSING_AXIS[transition] == "X" else np.abs(np.sin(theta))
    return np.where(near, 0.5 * np.sign(travelled) * along, 0.0)


def _columns(
    theta: np.ndarray, sign: float, radius: float, periods: dict[str, float], both: bool
) -> dict[str, np.ndarray]:
    """The shared signatures on one direction's samples (module docstring)."""
    c, n = np.cos(theta), np.sin(theta)
    columns = {
        "cos2": np.cos(2 * theta),
        "sin2": np.sin(2 * theta),
        "cos3": np.cos(3 * theta),
        "sin3": np.sin(3 * theta),
    }
    for transition in TRANSITIONS_DEG:
        axis, end = ENDS[transition]
        columns[f"backlash.{axis}.{end}"] = _step(theta, sign, transition)
    if both:
        columns["servo"] = sign * np.sin(2 * theta)
        columns["lateral.X"] = -sign * 0.5 * np.abs(n)
        columns["lateral.Y"] = sign * 0.5 * np.abs(c)
    for axis, period in periods.items():
        along, weight = (c, c) if axis == "X" else (n, n)
        phase = 2 * math.pi * radius * along / period
        columns[f"cyclic.{axis}.sin"] = weight * np.sin(phase)
        columns[f"cyclic.{axis}.cos"] = weight * np.cos(phase)
    return columns


def _kept(result: CircleResult, sign: float) -> np.ndarray:
    """The samples outside the quadrant transitions' spike windows."""
    near = np.zeros(len(result.angle_deg), dtype=bool)
    for transition in TRANSITIONS_DEG:
        travelled = travelled_since(result.angle_deg, transition, sign)
        near |= (travelled >= -SPIKE_LEAD_DEG) & (travelled <= SPIKE_WINDOW_DEG)
    return ~near


def cyclic_periods(machine: MachineScenario) -> dict[str, float]:
    """The period (m) of each plane axis' cyclic error: the geometry's, else its screw's lead."""
    periods = {}
    for axis in machine.axes:
        if axis.name in ("X", "Y"):
            cyclic = machine.geometry.cyclic.get(axis.name)
            periods[axis.name] = cyclic.period if cyclic is not None else axis.screw_lead()
    return periods


def ballbar_figures(
    results: Sequence[CircleResult], radius: float, periods: dict[str, float]
) -> dict[str, Any]:
    """The ballbar's diagnostics of a circle's directions (module docstring).

    Parameters
    ----------
    results
        The evaluation of one direction, or of both (CW and CCW) at the same feed.
    radius
        Nominal radius, m.
    periods
        Axis name -> period of its cyclic error, m (a screw's lead); an axis whose period
        exceeds the circle's diameter is not fitted (its ripple would be a low order).

    Returns
    -------
    dict
        JSON-ready figures: ``centre_offset_um``, ``scale_mismatch_um_per_m``,
        ``squareness_um_per_m``, ``servo_mismatch_ms``, ``straightness_um``, ``backlash_um``,
        ``lateral_play_um``, ``cyclic_error_um``, ``cyclic_period_mm``, ``reversal_spikes_um``
        and ``notes``.
    """
    both = len(results) == 2
    fitted = {axis: p for axis, p in periods.items() if p <= 2 * radius}
    rows, targets, directions = [], [], []
    for d, result in enumerate(results):
        sign = 1.0 if result.direction == "ccw" else -1.0
        keep = _kept(result, sign)
        theta = np.radians(result.angle_deg[keep])
        shared = _columns(theta, sign, radius, fitted, both)
        own = {
            f"{d}.radius": np.ones_like(theta),
            f"{d}.x0": np.cos(theta),
            f"{d}.y0": np.sin(theta),
        }
        rows.append({**shared, **own})
        targets.append(result.deviation_um[keep] * UM)
        directions.append(d)
    names = sorted({name for row in rows for name in row})
    design = np.vstack(
        [
            np.column_stack([row.get(name, np.zeros(len(target))) for name in names])
            for row, target in zip(rows, targets, strict=True)
        ]
    )
    value = dict(zip(names, _robust_fit(design, np.concatenate(targets)).tolist(), strict=True))
    speed = float(np.mean([r.speed_mm_min for r in results])) / 60e3  # m/s
    figures: dict[str, Any] = {
        "centre_offset_um": {
            "X": float(np.mean([value[f"{d}.x0"] for d in directions])) / UM,
            "Y": float(np.mean([value[f"{d}.y0"] for d in directions])) / UM,
        },
        "scale_mismatch_um_per_m": 2 * value["cos2"] / radius / UM,
        "squareness_um_per_m": -2 * value["sin2"] / radius / UM,
        "servo_mismatch_ms": -2 * value["servo"] / speed * 1e3 if both else None,
        "straightness_um": {"X": -4 * value["sin3"] / UM, "Y": 4 * value["cos3"] / UM},
        "backlash_um": {
            axis: {end: value[f"backlash.{axis}.{end}"] / UM for end in ("positive", "negative")}
            for axis in ("X", "Y")
        },
        "lateral_play_um": (
            {axis: value[f"lateral.{axis}"] / UM for axis in ("X", "Y")} if both else None
        ),
        "cyclic_error_um": {
            axis: math.hypot(value[f"cyclic.{axis}.sin"], value[f"cyclic.{axis}.cos"]) / UM
            if axis in fitted
            else None
            for axis in ("X", "Y")
        },
        "cyclic_period_mm": {axis: periods.get(axis, math.nan) * 1e3 for axis in ("X", "Y")},
        "reversal_spikes_um": _spikes(results),
        "notes": _notes(both, periods, fitted),
    }
    return figures


def _robust_fit(design: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Least squares, then again without the samples the signatures leave far off (beyond
    :data:`OUTLIER_SPREAD` times their robust spread and :data:`OUTLIER_FLOOR`): a ringing that
    outlasts a spike's window, a stick-slip, is no error of the list and would tilt them."""
    keep = np.ones(len(target), dtype=bool)
    for _ in range(ROBUST_ROUNDS):
        solution = np.linalg.lstsq(design[keep], target[keep], rcond=None)[0]
        residual = target - design @ solution
        spread = 1.4826 * np.median(np.abs(residual[keep] - np.median(residual[keep])))
        kept = np.abs(residual) <= max(OUTLIER_SPREAD * spread, OUTLIER_FLOOR)
        if np.array_equal(kept, keep) or kept.sum() < design.shape[1] * 4:
            break
        keep = kept
    return solution


def _spikes(results: Sequence[CircleResult]) -> dict[str, dict[str, float]]:
    """The reversal spikes' heights per axis and end (um), the mean of the directions."""
    spikes: dict[str, dict[str, float]] = {"X": {}, "Y": {}}
    for transition in TRANSITIONS_DEG:
        axis, end = ENDS[transition]
        heights = [s.height_um for r in results for s in r.spikes if s.angle_deg == transition]
        spikes[axis][end] = float(np.mean(heights))
    return spikes


def _notes(both: bool, periods: dict[str, float], fitted: dict[str, float]) -> list[str]:
    notes = []
    if not both:
        notes.append(
            "one direction: the ellipse at 45/135 degrees is reported as squareness (servo "
            "mismatch, which flips with the direction, and lateral play need both directions)"
        )
    for axis in sorted(set(periods) - set(fitted)):
        notes.append(
            f"cyclic error of {axis}: its period {periods[axis] * 1e3:g} mm exceeds the circle's "
            "diameter, not fitted"
        )
    return notes
