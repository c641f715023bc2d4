"""The multi-axis plant as an SSP package (System Structure and Parameterization, 1.0).

``export_ssp`` writes a zip ``.ssp`` with

- ``SystemStructure.ssd``: the system ``<machine>``, one component per axis (``X``, ``Y``,
  ``Z``) whose ``source`` is that axis' FMU under ``resources/``, its connectors (the plant
  contract's inputs and outputs), each axis' parameter set as parameter bindings (the axis'
  plant parameters, its start position), and the default experiment. The connection list is
  empty: the plant's axes do not act on one another (the closed loop, the controller, is the
  master's), and system-level connectors, which SSP allows for the inputs and outputs of the
  whole, are left out because OSP libcosim refuses a connection without a start element; an
  importer reaches each axis' variables as ``<axis>.<variable>``. The step size is the
  master's choice: the speed-loop period of the axes;
- ``resources/<axis>.fmu``: each axis' plant FMU;
- ``resources/<axis>.ssv``: each axis' parameter set as a stand-alone parameter-value file.

An independent master (OSP libcosim, through libcosimpy) loads it; :func:`open_loop` runs the
same plant in the project's own stepping (every axis its own instance, stepped in turn through
fmpy) with given current commands, for the comparison.
"""

from __future__ import annotations

import shutil
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from twin_cosim.contour.machine_run import MachinePlants
from twin_cosim.plant import CONTRACT_INPUTS, CONTRACT_OUTPUTS
from twin_cosim.scenario.machine import MachineScenario

SSD_NS = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC_NS = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV_NS = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"


def axis_parameters(machine: MachineScenario, start: Mapping[str, float]) -> dict[str, dict]:
    """Each axis' FMU parameters: its plant parameters and its start position (m)."""
    return {
        axis.name: {
            **axis.plant_parameters,
            "load_position_start": float(start.get(axis.name, 0.0)),
        }
        for axis in machine.axes
    }


def _parameter_set(name: str, values: Mapping[str, float], integers: set[str]) -> str:
    rows = []
    for key, value in values.items():
        kind = "Integer" if key in integers else "Real"
        text = str(int(value)) if kind == "Integer" else repr(float(value))
        rows.append(
            f'      <ssv:Parameter name={quoteattr(key)}><ssv:{kind} value="{text}"/>'
            "</ssv:Parameter>"
        )
    return (
        f'<ssv:ParameterSet xmlns:ssv="{SSV_NS}" version="1.0" name={quoteattr(name)}>\n'
        "    <ssv:Parameters>\n" + "\n".join(rows) + "\n    </ssv:Parameters>\n"
        "  </ssv:ParameterSet>"
    )


def _connector(name: str, kind: str) -> str:
    return f'<ssd:Connector name={quoteattr(name)} kind="{kind}"><ssc:Real/></ssd:Connector>'


def system_structure(
    machine: MachineScenario, parameters: Mapping[str, Mapping[str, float]], integers: set[str]
) -> str:
    """The ``SystemStructure.ssd`` text of the machine's plant."""
    components = []
    for axis in machine.axes:
        connectors = [_connector(v, "input") for v in CONTRACT_INPUTS]
        connectors += [_connector(v, "output") for v in CONTRACT_OUTPUTS]
        components.append(
            f'      <ssd:Component name="{axis.name}" type="application/x-fmu-sharedlibrary" '
            f'source="resources/{axis.name}.fmu">\n'
            "        <ssd:Connectors>\n          "
            + "\n          ".join(connectors)
            + "\n        </ssd:Connectors>\n"
            "        <ssd:ParameterBindings>\n"
            "          <ssd:ParameterBinding>\n"
            "            <ssd:ParameterValues>\n  "
            + _parameter_set(f"{axis.name}_parameters", parameters[axis.name], integers)
            + "\n            </ssd:ParameterValues>\n"
            "          </ssd:ParameterBinding>\n"
            "        </ssd:ParameterBindings>\n"
            "      </ssd:Component>"
        )
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<ssd:SystemStructureDescription xmlns:ssd="{SSD_NS}" xmlns:ssc="{SSC_NS}" '
        f'version="1.0" name={quoteattr(machine.name)}>\n'
        f"  <ssd:System name={quoteattr(machine.name)}>\n"
        "    <ssd:Elements>\n" + "\n".join(components) + "\n    </ssd:Elements>\n"
        "    <ssd:Connections/>\n"
        "  </ssd:System>\n"
        '  <ssd:DefaultExperiment startTime="0.0"/>\n'
        "</ssd:SystemStructureDescription>\n"
    )


def _integers(machine: MachineScenario) -> set[str]:
    from twin_cosim.plant_model import plant_model

    found = set()
    for axis in machine.axes:
        variables = plant_model(axis.model_name()).parameters
        found |= {n for n, v in variables.items() if v.type == "Integer"}
    return found


def export_ssp(
    machine: MachineScenario, path: Path | str, start: Mapping[str, float] | None = None
) -> Path:
    """Write the machine's plant as an SSP package; returns ``path``.

    Parameters
    ----------
    machine
        The machine: each axis' FMU and plant parameters.
    path
        The ``.ssp`` file to write.
    start
        Axis name -> start position (m); 0 for the axes not named.
    """
    path = Path(path)
    parameters = axis_parameters(machine, start or {})
    integers = _integers(machine)
    partial = path.with_name(path.name + ".partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("SystemStructure.ssd", system_structure(machine, parameters, integers))
        for axis in machine.axes:
            archive.write(axis.plant_fmu(), f"resources/{axis.name}.fmu")
            text = '<?xml version="1.0" encoding="UTF-8"?>\n' + _parameter_set(
                f"{axis.name}_parameters", parameters[axis.name], integers
            )
            archive.writestr(f"resources/{axis.name}.ssv", text + "\n")
    partial.replace(path)
    return path


def unpacked(path: Path | str) -> Path:
    """An SSP package unpacked into a new temporary folder (the caller removes it)."""
    folder = Path(tempfile.mkdtemp(prefix="twin-ssp-"))
    try:
        with zipfile.ZipFile(path) as archive:
            archive.extractall(folder)
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise
    return folder


def open_loop(
    machine: MachineScenario,
    currents: Mapping[str, np.ndarray],
    start: Mapping[str, float] | None = None,
) -> dict[str, np.ndarray]:
    """The machine's plant stepped by the project through fmpy, open loop, every axis in turn.

    Parameters
    ----------
    machine
        The machine.
    currents
        Axis name -> current command (A) held over each speed-loop period, one per step.
    start
        Axis name -> start position (m).

    Returns
    -------
    dict
        Axis name -> outputs after every step, shape (steps, outputs of the plant contract).
    """
    parameters = axis_parameters(machine, start or {})
    h = machine.axes[0].settings.speed_period
    steps = len(next(iter(currents.values())))
    found = {name: np.empty((steps, len(CONTRACT_OUTPUTS))) for name in machine.axis_names}
    with MachinePlants(machine) as plants:
        refs = {}
        for name, plant in plants.plants.items():
            plant.start_run(parameters[name])
            refs[name] = (
                [plant.value_reference(v) for v in CONTRACT_INPUTS],
                [plant.value_reference(v) for v in CONTRACT_OUTPUTS],
            )
        for k in range(steps):
            for name, plant in plants.plants.items():
                inputs, outputs = refs[name]
                plant.set_reals(inputs, [float(currents[name][k]), 0.0])
                plant.do_step(k * h, h)
                found[name][k] = plant.get_reals(outputs)
    return found
