"""``modelDescription.xml`` of a model for FMI 2.0 or FMI 3.0 co-simulation, and the FMI 3.0
``sources/buildDescription.xml``, from its variable table.

Both versions describe the same variables with the same value references, units, ranges, log
categories and default experiment; they differ in how they spell them: FMI 2.0 wraps each
variable in a ``ScalarVariable`` with a ``Real`` or ``Integer`` child and numbers the model
structure by 1-based index, FMI 3.0 has ``Float64`` and ``Int32`` elements and refers to
variables by value reference; FMI 3.0 names the GUID the instantiation token and lists its source
files in the build description instead of the model description.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from fmu_build.generate import GENERATION_TOOL, LOG_CATEGORIES, model_guid
from fmu_build.variable_table import TIME, Variable, VariableTable

FMI_VERSIONS = (2, 3)
DEFAULT_STOP_TIME_S = 1.0
# The FMI 3.0 element of each type of the variable table (FMI 2.0 uses the table's names).
FMI3_TYPES = {"Real": "Float64", "Integer": "Int32"}


def _xml(root: ET.Element) -> str:
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _number(value: float | int) -> str:
    return repr(value) if isinstance(value, int) else repr(float(value))


def _root(table: VariableTable, fmi_version: int) -> ET.Element:
    attributes = {"fmiVersion": f"{fmi_version}.0", "modelName": table.name}
    attributes["guid" if fmi_version == 2 else "instantiationToken"] = model_guid(table)
    attributes |= {
        "description": table.description,
        "generationTool": GENERATION_TOOL,
        "version": table.version,
        "variableNamingConvention": "flat",
    }
    if fmi_version == 2:
        attributes["numberOfEventIndicators"] = "0"
    return ET.Element("fmiModelDescription", attributes)


def _co_simulation(root: ET.Element, table: VariableTable, source_files: list[str]) -> None:
    """FMI 3.0 adds the (trivial) event mode: no event is ever signalled, but an importer that
    asks for it may use it to set inputs between steps."""
    attributes = {"modelIdentifier": table.name, "canHandleVariableCommunicationStepSize": "true"}
    if root.get("fmiVersion") == "3.0":
        ET.SubElement(root, "CoSimulation", attributes | {"hasEventMode": "true"})
        return
    files = ET.SubElement(ET.SubElement(root, "CoSimulation", attributes), "SourceFiles")
    for name in source_files:
        ET.SubElement(files, "File", {"name": name})


def _units_categories_experiment(root: ET.Element, table: VariableTable) -> None:
    """UnitDefinitions, LogCategories and DefaultExperiment, the same in both versions."""
    unit_defs = ET.SubElement(root, "UnitDefinitions")
    for unit in sorted({v.unit for v in table.variables if v.unit != "1"}):
        element = ET.SubElement(unit_defs, "Unit", {"name": unit})
        exponents = {k: str(e) for k, e in table.units[unit].items()}
        ET.SubElement(element, "BaseUnit", exponents)
    categories = ET.SubElement(root, "LogCategories")
    for name, description in LOG_CATEGORIES:
        ET.SubElement(categories, "Category", {"name": name, "description": description})
    ET.SubElement(
        root,
        "DefaultExperiment",
        {
            "startTime": "0.0",
            "stopTime": repr(DEFAULT_STOP_TIME_S),
            "stepSize": repr(table.default_step_size),
        },
    )


def _variable_attributes(v: Variable) -> dict[str, str]:
    """Name, value reference, description, causality, variability and initial."""
    if v.causality == "parameter":
        variability = "fixed"
    else:
        variability = "continuous" if v.type == "Real" else "discrete"
    attributes = {
        "name": v.name,
        "valueReference": str(v.value_reference),
        "description": v.description,
        "causality": v.causality,
        "variability": variability,
    }
    if v.causality == "parameter":
        attributes["initial"] = "exact"
    return attributes


def _value_attributes(v: Variable) -> dict[str, str]:
    """Unit, start, min and max."""
    attributes = {}
    if v.unit != "1" and v.type == "Real":
        attributes["unit"] = v.unit
    if v.start is not None:
        attributes["start"] = _number(v.start)
    if v.min is not None or v.positive:
        attributes["min"] = _number(v.min if v.min is not None else 0.0)
    if v.max is not None:
        attributes["max"] = _number(v.max)
    return attributes


def _model_variables(root: ET.Element, table: VariableTable, fmi_version: int) -> None:
    """The table's variables; FMI 3.0 first declares its independent variable, time."""
    variables = ET.SubElement(root, "ModelVariables")
    if fmi_version == 3:
        time = {
            "name": TIME,
            "valueReference": str(table.time_value_reference),
            "description": "Simulation time",
            "causality": "independent",
            "variability": "continuous",
            "unit": "s",  # defined: every table has sample_period in s
        }
        ET.SubElement(variables, "Float64", time)
    for v in table.variables:
        if fmi_version == 2:
            element = ET.SubElement(variables, "ScalarVariable", _variable_attributes(v))
            ET.SubElement(element, v.type, _value_attributes(v))
        else:
            attributes = _variable_attributes(v) | _value_attributes(v)
            ET.SubElement(variables, FMI3_TYPES[v.type], attributes)


def _model_structure(root: ET.Element, table: VariableTable, fmi_version: int) -> None:
    """Outputs list the inputs they depend on directly (none for an output of the state alone);
    initial unknowns declare no dependencies: in initialization mode they follow every known.
    FMI 2.0 refers to a variable by its 1-based index in ModelVariables, FMI 3.0 by its value
    reference."""
    if fmi_version == 2:
        key = "index"
        reference = {v.name: index for index, v in enumerate(table.variables, start=1)}
    else:
        key = "valueReference"
        reference = {v.name: v.value_reference for v in table.variables}
    produced = [v for v in table.variables if v.causality == "output"]
    outputs, initial = [], []
    for v in produced:
        attributes = {
            key: str(reference[v.name]),
            "dependencies": " ".join(str(reference[name]) for name in v.depends_on),
        }
        if v.depends_on:
            attributes["dependenciesKind"] = " ".join("dependent" for _ in v.depends_on)
        outputs.append(attributes)
        initial.append({key: str(reference[v.name])})
    structure = ET.SubElement(root, "ModelStructure")
    if fmi_version == 2:
        groups = [(ET.SubElement(structure, "Outputs"), "Unknown", outputs)]
        groups.append((ET.SubElement(structure, "InitialUnknowns"), "Unknown", initial))
    else:
        groups = [(structure, "Output", outputs), (structure, "InitialUnknown", initial)]
    for parent, tag, rows in groups:
        for attributes in rows:
            ET.SubElement(parent, tag, attributes)


def model_description(table: VariableTable, source_files: list[str], fmi_version: int) -> str:
    """``modelDescription.xml`` for co-simulation.

    Parameters
    ----------
    table
        The model's variable table.
    source_files
        Names of the C files in ``sources/`` (FMI 2.0 lists them here; FMI 3.0 in
        :func:`build_description`).
    fmi_version
        2 or 3.
    """
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi_version!r}: expected one of {FMI_VERSIONS}")
    root = _root(table, fmi_version)
    _co_simulation(root, table, source_files)
    _units_categories_experiment(root, table)
    _model_variables(root, table, fmi_version)
    _model_structure(root, table, fmi_version)
    return _xml(root)


def build_description(table: VariableTable, source_files: list[str]) -> str:
    """``sources/buildDescription.xml`` of an FMI 3.0 FMU: the C99 files that build its binary
    (the headers sit beside them in ``sources/``)."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    configuration = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": table.name})
    file_set = ET.SubElement(configuration, "SourceFileSet", {"language": "C99"})
    for name in source_files:
        ET.SubElement(file_set, "SourceFile", {"name": name})
    return _xml(root)
