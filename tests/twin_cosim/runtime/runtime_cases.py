"""What the runtime twin's tests share: a short production cycle (a move out and back with a
reversal while moving, 1.3 s), its scenario file, and a virtual machine running it."""

from __future__ import annotations

from pathlib import Path

from scenario_texts import scenario_text

from twin_cosim.runtime.virtual_machine import Drift, VirtualMachine, draw_machine
from twin_cosim.scenario import Scenario, resolve_scenario


def cycle_file(folder: Path) -> Path:
    """The cycle's scenario file in ``folder``: dwell, 20 mm/s out, back, stop, dwell."""
    path = folder / "cycle.yaml"
    text = scenario_text("cycle", speed=0.02, acceleration=0.2, move=0.4, stop=0.2, dwell=0.15)
    path.write_text(text)
    return path


def cycle(folder: Path) -> Scenario:
    """The cycle's scenario."""
    return resolve_scenario(cycle_file(folder))


def machine(
    scenario: Scenario, drifts: list[Drift] | None = None, start: int = 0, seed: int = 3
) -> VirtualMachine:
    """The cycle's virtual machine: 2 % calibration error, 20 nm and 5 mA of noise."""
    return draw_machine(
        scenario, str(scenario.plant_fmu()), [], drifts or [], start, perturb=0.02, seed=seed
    )
