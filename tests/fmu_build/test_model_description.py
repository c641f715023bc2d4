"""The generated modelDescription.xml of each FMI version follows the variable table: variables,
value references, types, units, dependencies, default experiment, log categories, source files;
FMI 3.0 adds its independent variable time and the build description."""

from __future__ import annotations

import zipfile
from xml.etree import ElementTree

import pytest
from fmpy import read_model_description

from fmu_build import build, generate
from fmu_build.model_description import FMI3_TYPES, model_description
from fmu_build.variable_table import VariableTable, load_variable_table


def load_table(model: str) -> VariableTable:
    return load_variable_table(
        build.MODELS_DIR / model / "variables.yaml", build.COMMON_DIR / "units.yaml"
    )


def test_model_description_follows_the_variable_table(any_fmu):
    model, version, fmu_path = any_fmu
    table = load_table(model)
    description = read_model_description(str(fmu_path))
    by_name = {v.name: v for v in description.modelVariables}
    time = {"time"} if version == 3 else set()  # FMI 3.0's independent variable
    assert set(by_name) == {v.name for v in table.variables} | time
    for v in table.variables:
        xml = by_name[v.name]
        assert (xml.valueReference, xml.causality, xml.type) == (
            v.value_reference,
            v.causality,
            v.type if version == 2 else FMI3_TYPES[v.type],
        )
        if v.type == "Real":
            assert (xml.unit or "1") == v.unit
    outputs = [u.variable.name for u in description.outputs]
    assert outputs == [v.name for v in table.variables if v.causality == "output"]
    units = {u.name: u.baseUnit for u in description.unitDefinitions}
    for name, unit in units.items():
        for base in ("kg", "m", "s", "A", "rad"):
            assert getattr(unit, base) == table.units[name].get(base, 0), (name, base)


def test_fmi3_declares_time_as_its_independent_variable():
    for model in ("drive2mass", "emps"):
        table = load_table(model)
        description = read_model_description(str(build.build_fmu(model, fmi_version=3)))
        independent = [v for v in description.modelVariables if v.causality == "independent"]
        assert [(v.name, v.type, v.unit) for v in independent] == [("time", "Float64", "s")]
        assert independent[0].valueReference == table.time_value_reference
        assert table.time_value_reference not in {v.value_reference for v in table.variables}
        assert description.guid == generate.model_guid(table)  # the instantiation token
        assert description.coSimulation.hasEventMode


def test_outputs_declare_their_direct_inputs(any_fmu):
    model, _, fmu_path = any_fmu
    table = load_table(model)
    description = read_model_description(str(fmu_path))
    assert description.outputs, "no ModelStructure outputs"
    for unknown in description.outputs:
        declared = table.by_name(unknown.variable.name).depends_on
        # fmpy reads dependencies="" as an empty list: the output depends on no input
        assert unknown.dependencies is not None, unknown.variable.name
        assert [d.name for d in unknown.dependencies] == list(declared)
        assert all(d.causality == "input" for d in unknown.dependencies)
    state_outputs = [u for u in description.outputs if not u.dependencies]
    assert {"motor_angle", "motor_speed", "load_position", "load_speed"} <= {
        u.variable.name for u in state_outputs
    }


def test_default_experiment_step_is_the_sample_period(any_fmu):
    model, _, fmu_path = any_fmu
    description = read_model_description(str(fmu_path))
    sample_period = next(v for v in description.modelVariables if v.name == "sample_period")
    assert float(description.defaultExperiment.stepSize) == float(sample_period.start)
    assert (
        float(sample_period.start) == {"drive2mass": 62.5e-6, "emps": 1e-3, "hsm150": 1e-3}[model]
    )


def test_log_categories_are_declared(any_fmu):
    root = ElementTree.parse(zipfile.ZipFile(any_fmu.path).open("modelDescription.xml")).getroot()
    names = [c.get("name") for c in root.iter("Category")]
    assert names == [name for name, _ in generate.LOG_CATEGORIES]
    assert {"logEvents", "logStatusError"} <= set(names)


def test_the_source_files_that_build_the_binary_are_listed(any_fmu):
    """FMI 2.0 lists them in modelDescription.xml, FMI 3.0 in sources/buildDescription.xml:
    exactly the C files in sources/, the version's API file among them."""
    description = read_model_description(str(any_fmu.path))
    (configuration,) = description.buildConfigurations
    assert configuration.modelIdentifier == any_fmu.model
    (file_set,) = configuration.sourceFileSets
    in_archive = sorted(
        name.removeprefix("sources/")
        for name in zipfile.ZipFile(any_fmu.path).namelist()
        if name.startswith("sources/") and name.endswith(".c")
    )
    assert sorted(file_set.sourceFiles) == in_archive
    assert f"fmi{any_fmu.fmi_version}_slave.c" in in_archive


def test_an_unknown_fmi_version_is_refused():
    with pytest.raises(ValueError, match="FMI version 4: expected one of"):
        model_description(load_table("emps"), ["model.c"], 4)
