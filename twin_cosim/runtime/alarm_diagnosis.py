"""The full diagnosis an alarm asks for, restricted to what the alarm points at and to the recent
windows, run in a process of its own while the twin keeps checking windows.

What it runs: :func:`twin_cosim.gap.diagnosis.diagnose` (the whole pipeline: floors, where,
rounds of fits judged on held-out data against the noise and calibration floors) of the
baseline twin, with one effect at most and the hypotheses near the alarmed one: the tracked
effects (the alarmed one among them), or the plant model's whole library for an alarm on the
unexplained gap. The data: the first window from the alarm's on whose gap is at least
:data:`DIAGNOSABLE_GAP` times the noise floor (the sequential test sees a drift of a fraction
of the noise floor that no single window can show: the diagnosis waits for one that can, at
most :data:`LONGEST_WAIT` windows) and the one after it: the fit on the first, the judgement
on the second (a cycle's half may hold no reversal, which the diagnosis needs in each part);
when the two ran different references, or the wait ran out, the last window is split in
time. The calibration tolerance is how well the baseline calibration knows the calibrated
parameters (three of their standard errors, at least :data:`LEAST_TOLERANCE`; the datasheet
tolerance of the diagnosis when the baseline came from a plant file): a drift since the
baseline is not calibration error. Its replays run on :data:`WORKERS` processes. Its answer
joins the alarm: the effect accepted (or none), the held-out gap before and after it, and how
long it took (the wall time, and the diagnosis' own estimate of the wall time on otherwise
idle cores).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

from twin_cosim.measured import MeasuredRun
from twin_cosim.scenario import Scenario

DIAGNOSABLE_GAP = 1.5  # normalised RMS gap of a window worth diagnosing
LONGEST_WAIT = 10  # windows after the alarm: the diagnosis runs then at the latest
LEAST_TOLERANCE = 0.001  # relative
WORKERS = 2  # replay processes of the diagnosis: the two cores of a small machine


def alarm_tolerance(precision: float | None) -> float:
    """The calibration tolerance of an alarm's diagnosis from the baseline calibration's
    precision (relative; None: no calibration, the diagnosis' own tolerance)."""
    from twin_cosim.gap.settings import DiagnosisSettings

    if precision is None:
        return DiagnosisSettings().calibration_tolerance
    return max(3.0 * precision, LEAST_TOLERANCE)


@dataclass(frozen=True)
class AlarmJob:
    """What the diagnosis of one alarm needs (sent to its process).

    Attributes
    ----------
    alarm : int
        The alarm's number (0 for the first).
    window : int
        The alarm's window.
    effect : str
        The alarmed effect (or ``unexplained``).
    scenario : Scenario
        The window's scenario with the baseline twin's plant parameters.
    training : MeasuredRun
        The window the effects are fitted on.
    holdout : MeasuredRun or None
        The window they are judged on (None: ``training`` is split in time).
    hypotheses : tuple of str or None
        The hypotheses to fit (None: the whole library).
    fmu : str
        The plant FMU.
    alarm_window : int
        The window at which the alarm was raised (``window`` may come later: the first whose
        gap is large enough to diagnose).
    calibration_tolerance : float
        How well the baseline twin's calibrated parameters are known (relative).
    """

    alarm: int
    window: int
    effect: str
    scenario: Scenario
    training: MeasuredRun
    holdout: MeasuredRun | None
    hypotheses: tuple[str, ...] | None
    fmu: str
    alarm_window: int
    calibration_tolerance: float


def with_baseline(scenario: Scenario, parameters: dict[str, float]) -> Scenario:
    """The scenario with the baseline twin's FMU parameters."""
    return dataclasses.replace(
        scenario, plant_parameters={**scenario.plant_parameters, **parameters}
    )


def run_alarm_diagnosis(job: AlarmJob) -> dict[str, Any]:
    """Run the diagnosis of one alarm; what the log records of it."""
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.gap.settings import DiagnosisSettings

    start = time.perf_counter()
    settings = DiagnosisSettings(
        max_effects=1, hypotheses=job.hypotheses, calibration_tolerance=job.calibration_tolerance
    )
    holdout = [job.holdout] if job.holdout is not None else []
    found = diagnose(job.scenario, [job.training], holdout, job.fmu, settings, workers=WORKERS)
    remaining = found.remaining
    accepted = [a if isinstance(a, str) else "+".join(a) for a in found.accepted]
    before, after = remaining.normalised_rms_before, remaining.times_noise_floor
    return {
        "event": "diagnosis",
        "alarm": job.alarm,
        "window": job.window,
        "alarm_window": job.alarm_window,
        "alarmed_effect": job.effect,
        "calibration_tolerance": job.calibration_tolerance,
        "hypotheses": list(job.hypotheses) if job.hypotheses else "library",
        "held_out": "the next window" if job.holdout is not None else "the window's second half",
        "significant": bool(found.significant),
        "accepted": accepted,
        "effect": accepted[0] if accepted else None,
        "agrees": bool(accepted) and job.effect in accepted[0].split("+"),
        "gap_before": before,
        "gap_after": after,
        "gap_shrinks_by": 1.0 - after / before if before > 0 else 0.0,
        "position_rms_um_before": remaining.position_rms_um_before,
        "position_rms_um_after": remaining.position_rms_um,
        "verdict": found.verdict,
        "seconds": time.perf_counter() - start,
        "idle_wall_s": found.times["diagnosis"]["idle_wall_estimate_s"],
        "workers": WORKERS,
    }


def warm_up() -> None:
    """Import what the diagnosis uses (a pool's initializer: the first alarm waits less)."""
    import twin_cosim.gap.diagnosis  # noqa: F401
