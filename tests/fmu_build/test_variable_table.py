"""The variable table loader names the file and the entry on every mistake."""

from __future__ import annotations

import pytest

from fmu_build.build import COMMON_DIR
from fmu_build.variable_table import VariableTableError, load_variable_table

HEADER = "model: {name: m, description: d, version: '1'}\nvariables:\n"


def table(tmp_path, body: str):
    path = tmp_path / "variables.yaml"
    path.write_text(HEADER + body)
    return load_variable_table(path, COMMON_DIR / "units.yaml")


def test_value_references_are_dense_reals_first(tmp_path):
    t = table(
        tmp_path,
        """
  - {name: n, causality: parameter, type: Integer, start: 1, description: x}
  - {name: a, causality: input, unit: A, start: 0.0, description: x}
  - {name: y, causality: output, unit: m, description: x}
""",
    )
    assert [(v.name, v.value_reference) for v in t.variables] == [("a", 0), ("y", 1), ("n", 2)]


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            "  - {name: a, causality: input, unit: A, start: 0.0, description: x, colour: red}\n",
            "unknown keys",
        ),
        (
            "  - {name: a, causality: state, unit: A, start: 0.0, description: x}\n",
            "causality must be",
        ),
        (
            "  - {name: a, causality: input, unit: furlong, start: 0.0, description: x}\n",
            "unit 'furlong'",
        ),
        ("  - {name: a, causality: input, unit: A, description: x}\n", "needs a start value"),
        (
            "  - {name: a, causality: input, unit: A, start: .nan, description: x}\n",
            "finite number",
        ),
        (
            "  - {name: a, causality: input, unit: A, start: 2.0, max: 1.0, description: x}\n",
            "outside",
        ),
        ("  - {name: a, causality: input, unit: A, start: 0.0, description: x}\n" * 2, "duplicate"),
        (
            "  - {name: a b, causality: input, unit: A, start: 0.0, description: x}\n",
            "C identifier",
        ),
        ("  - {name: a, causality: input, unit: A, start: 0.0}\n", "description is required"),
    ],
)
def test_mistakes_are_named(tmp_path, body, message):
    with pytest.raises(VariableTableError, match=message) as info:
        table(tmp_path, body)
    assert "variables.yaml" in str(info.value)


def test_malformed_yaml_is_named(tmp_path):
    with pytest.raises(VariableTableError, match="malformed YAML"):
        table(tmp_path, "  - {name: [\n")
