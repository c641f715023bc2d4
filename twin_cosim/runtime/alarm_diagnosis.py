"""The full diagnosis an alarm asks for, restricted to what the alarm points at and to the recent
windows, run in a process of its own while the twin keeps checking windows.

What it runs: :func:`twin_cosim.gap.diagnosis.diagnose` (the whole pipeline: floors, where,
rounds of fits judged on held-out data against the noise and calibration floors) of the
baseline twin, with one effect at most and the hypotheses near the alarmed one: the tracked
effects (the alarmed one among them), or the plant model's whole library for an alarm on the
unexplained gap. The training data is the alarm's window; the held-out data the window before
it when both ran the same reference, else the alarm's window is split in time. Its answer joins
the alarm: the effect accepted (or none), the held-out gap before and after it, and how long it
took.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

from twin_cosim.measured import MeasuredRun
from twin_cosim.scenario import Scenario


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
        The alarm's window.
    holdout : MeasuredRun or None
        The window before it, when it ran the same reference.
    hypotheses : tuple of str or None
        The hypotheses to fit (None: the whole library).
    fmu : str
        The plant FMU.
    """

    alarm: int
    window: int
    effect: str
    scenario: Scenario
    training: MeasuredRun
    holdout: MeasuredRun | None
    hypotheses: tuple[str, ...] | None
    fmu: str


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
    settings = DiagnosisSettings(max_effects=1, hypotheses=job.hypotheses)
    holdout = [job.holdout] if job.holdout is not None else []
    found = diagnose(job.scenario, [job.training], holdout, job.fmu, settings, workers=1)
    remaining = found.remaining
    accepted = [a if isinstance(a, str) else "+".join(a) for a in found.accepted]
    before, after = remaining.normalised_rms_before, remaining.times_noise_floor
    return {
        "event": "diagnosis",
        "alarm": job.alarm,
        "window": job.window,
        "alarmed_effect": job.effect,
        "hypotheses": list(job.hypotheses) if job.hypotheses else "library",
        "held_out": "the window before" if job.holdout is not None else "time split",
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
    }


def warm_up() -> None:
    """Import what the diagnosis uses (a pool's initializer: the first alarm waits less)."""
    import twin_cosim.gap.diagnosis  # noqa: F401
