"""Loading a machine scenario (a file with ``axes:``) into a :class:`MachineScenario`.

Layout (``axes`` is required, every other section optional)::

    name: xy_table
    description: free text
    axes: {X: {...}, Y: {...}}          # twin_cosim.scenario.axes_section
    interpolation:
      sample_period: 0.004              # s: the CNC's interpolation period
    program: part.nc                    # a part program (G-code), relative to the file
    run:
      settle: 0.2                       # s of standstill recorded after the path's end
      max_samples: 2400000              # position-loop samples a run may have at most
    optimize: {...}                     # contour tuning (twin_cosim.contour.tuning)
    diagnose: {...}                     # the diagnosis of each axis (twin_cosim.gap.settings)

Every error names the file and the key path.
"""

from __future__ import annotations

from pathlib import Path

from twin_cosim.reference import ReferenceError, check_periods
from twin_cosim.scenario.axes_section import axes_section
from twin_cosim.scenario.loader import MAX_SAMPLES, NAME_PATTERN
from twin_cosim.scenario.machine import MachineScenario
from twin_cosim.scenario.shipped import find_scenario
from twin_cosim.schema import Checker, load_yaml

TOP_KEYS = {
    "name",
    "description",
    "axes",
    "interpolation",
    "program",
    "run",
    "optimize",
    "diagnose",
}


def is_machine_scenario(path: Path | str) -> bool:
    """Whether a scenario file (or shipped name) describes a machine (has ``axes:``)."""
    data = load_yaml(find_scenario(path))
    return isinstance(data, dict) and "axes" in data


def load_machine(path: Path | str) -> MachineScenario:
    """Load and check a machine scenario (a path or the name of a shipped one).

    Raises
    ------
    ScenarioError
        On malformed YAML, unknown keys, wrong types, non-finite or out-of-range values; the
        message names the file and the key path.
    """
    source = find_scenario(path)
    check = Checker(source)
    data = check.mapping(load_yaml(source), "(top level)", TOP_KEYS)
    if "axes" not in data:
        raise check.fail("axes", "an axes section (X, Y and optionally Z)")
    name = str(data.get("name", source.stem))
    if not NAME_PATTERN.fullmatch(name):
        raise check.fail("name", "a plain file name (letters, digits, '.', '_', '-')", name)
    axes = axes_section(check, data["axes"])
    interpolation = check.mapping(data.get("interpolation"), "interpolation", {"sample_period"})
    sample_period = check.number(
        interpolation.get("sample_period", 0.004), "interpolation.sample_period", positive=True
    )
    try:
        check_periods(sample_period, axes[0].settings.position_period)
    except ReferenceError as exc:
        raise check.fail("interpolation.sample_period", str(exc), sample_period) from None
    run = check.mapping(data.get("run"), "run", {"settle", "max_samples"})
    program = data.get("program")
    return MachineScenario(
        name=name,
        description=str(data.get("description", "")),
        source=source,
        axes=axes,
        sample_period=sample_period,
        program=None if program is None else source.parent / check.text(program, "program"),
        settle=check.number(run.get("settle", 0.2), "run.settle", minimum=0.0),
        max_samples=int(
            check.number(run.get("max_samples", MAX_SAMPLES), "run.max_samples", minimum=2)
        ),
        optimize=check.mapping(data.get("optimize"), "optimize"),
        diagnose=check.mapping(data.get("diagnose"), "diagnose"),
    )
