"""The auto-tuner on a scenario: its plant FRF (a file, or measured on the twin), the proposed
set, its run on the scenario beside the scenario's own set.

Measured on the twin, the plant FRF is taken as a tuner takes it on a machine with friction and
backlash: at an operating motor speed of :data:`MOTOR_SPEED_RAD_S` (friction slides in one
direction, the backlash stays closed) with a multisine of :data:`EXCITATION_SHARE` of the
current limit (small enough not to open the backlash), the nonlinearities on.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from twin_cosim.cosim import run_scenario
from twin_cosim.frequency.autotune import (
    DESIGN_POINTS,
    LOW_HZ,
    PHASE_MARGIN_DEG,
    Autotuned,
    autotune,
    design_plant,
)
from twin_cosim.frequency.frf_file import DEFAULT_COHERENCE_FLOOR, read_frf
from twin_cosim.frequency.loops import LinearLoops
from twin_cosim.frequency.margins import dense_grid
from twin_cosim.frequency.measurement import MeasurementSettings, measure
from twin_cosim.frequency.plots import plot_bode
from twin_cosim.frequency.response import PLANT_BAND, FrequencyResponse
from twin_cosim.metrics import compute_metrics
from twin_cosim.plant import Plant
from twin_cosim.scenario import Scenario, with_controller_set

MOTOR_SPEED_RAD_S = 20.0
EXCITATION_SHARE = 0.02


def twin_plant_frf(plant: Plant, scenario: Scenario) -> FrequencyResponse:
    """The plant FRF measured on the twin as the tuner measures it (nonlinearities on)."""
    settings = scenario.settings
    how = MeasurementSettings(
        "plant",
        speed=MOTOR_SPEED_RAD_S * settings.travel_per_rad,
        amplitude=EXCITATION_SHARE * settings.current_limit,
    )
    start = float(scenario.reference.position[0])
    measured = measure(plant, scenario.tuned, settings, scenario.plant_parameters, how, start)
    return measured.below(PLANT_BAND * 0.5 / settings.speed_period)


def propose(
    plant: Plant,
    scenario: Scenario,
    frf: Path | None = None,
    phase_margin: float = PHASE_MARGIN_DEG,
    coherence_floor: float = DEFAULT_COHERENCE_FLOOR,
) -> tuple[Autotuned, list[str]]:
    """The tuner's proposal for ``scenario`` from ``frf`` (or the twin's measured plant FRF on
    ``plant``), and the FRF file's masked bands in words."""
    started = time.perf_counter()
    if frf is None:
        measured = twin_plant_frf(plant, scenario)
        lines = (measured.frequency_hz, measured.response, measured.coherence)
        settings = scenario.settings
        source = (
            f"twin bode {scenario.name} --loop plant --speed "
            f"{MOTOR_SPEED_RAD_S * settings.travel_per_rad:.4g} --amplitude "
            f"{EXCITATION_SHARE * settings.current_limit:.4g} (the twin, measured)"
        )
        notes: list[str] = []
    else:
        data = read_frf(frf, coherence_floor)
        coherence = None if data.coherence is None else data.coherence[data.used]
        lines = (data.frequency_hz[data.used], data.response[data.used], coherence)
        source, notes = str(frf), data.notes(coherence_floor)
    proposal = autotune(
        *lines, scenario.tuned, scenario.settings, source, phase_margin, started=started
    )
    return proposal, notes


def autotune_scenario(
    scenario: Scenario,
    frf: Path | None,
    fmu: Path | None,
    phase_margin: float,
    coherence_floor: float,
) -> tuple[Autotuned, dict[str, Any]]:
    """Tune the scenario's controller from ``frf`` (or the twin's measured plant FRF).

    Returns
    -------
    tuple
        The proposal, and the metrics of a run of the scenario with it (``metrics``) and with
        the scenario's own set (``scenario_metrics``), plus the FRF's masked bands (``notes``)
        and the whole wall time (``wall_s``, s).
    """
    started = time.perf_counter()
    with Plant(scenario.plant_fmu(fmu)) as plant:
        proposal, notes = propose(plant, scenario, frf, phase_margin, coherence_floor)
        tuned_scenario = with_controller_set(scenario, proposal.controller_set)
        window = scenario.metrics_window
        metrics = compute_metrics(run_scenario(plant, tuned_scenario), window).as_dict()
        own = compute_metrics(run_scenario(plant, scenario), window).as_dict()
    return proposal, {
        "metrics": metrics,
        "scenario_metrics": own,
        "notes": notes,
        "wall_s": time.perf_counter() - started,
    }


def plot_design(proposal: Autotuned, scenario: Scenario, path: Path, command: str) -> Path:
    """The speed loop of the proposed set and of the scenario's own, on the fitted plant (the
    design model), the proposal's margins marked; ``command`` made it."""
    plant = design_plant(proposal.fit, scenario.settings)
    grid = dense_grid(LOW_HZ, 0.5 / scenario.settings.speed_period, DESIGN_POINTS)
    settings = proposal.controller_set.settings_for(scenario.settings)
    responses = {}
    for label, tuned, chosen in (
        ("twin autotune", proposal.controller_set.tuned, settings),
        ("the scenario's set", scenario.tuned, scenario.settings),
    ):
        loop = LinearLoops(plant, tuned, chosen).speed_open().siso(grid)
        responses[label] = FrequencyResponse("speed", "open", grid, loop)
    title = f"{scenario.name}: speed loop, open, on the fitted plant\n{command}"
    return plot_bode(responses, title, path, proposal.speed_margins)
