"""The variable table loader names the file and the entry on every mistake."""

from __future__ import annotations

import pytest

from fmu_build.build import COMMON_DIR
from fmu_build.variable_table import VariableTableError, load_variable_table

HEADER = "model: {name: m, description: d, version: '1'}\nvariables:\n"
STEP = (
    "  - {name: sample_period, causality: parameter, unit: s, start: 1.0e-3, positive: true,"
    " description: x}\n"
)


def table(tmp_path, body: str, step: str = STEP):
    path = tmp_path / "variables.yaml"
    path.write_text(HEADER + body + step)
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
    assert [(v.name, v.value_reference) for v in t.variables] == [
        ("a", 0),
        ("y", 1),
        ("sample_period", 2),
        ("n", 3),
    ]
    assert t.default_step_size == 1.0e-3
    assert t.time_value_reference == 4  # FMI 3.0's time: the first reference after the table


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
        (
            "  - {name: a, causality: input, unit: A, start: 0.0, description: x}\n"
            "  - {name: y, causality: output, unit: m, depends_on: [b], description: x}\n",
            r"depends_on names \['b'\], which are not inputs",
        ),
        (
            "  - {name: a, causality: input, unit: A, start: 0.0, depends_on: [a],"
            " description: x}\n",
            "only an output takes depends_on",
        ),
        (
            "  - {name: time, causality: input, unit: s, start: 0.0, description: x}\n",
            "the name 'time' is reserved for the independent variable of FMI 3.0",
        ),
        (
            "  - {name: n_1, causality: parameter, unit: m, start: 0.0, description: x}\n"
            "  - {name: n_3, causality: parameter, unit: m, start: 0.0, description: x}\n",
            r"n_k must be numbered 1 to n without gaps, got k = \[1, 3\]",
        ),
    ],
)
def test_mistakes_are_named(tmp_path, body, message):
    with pytest.raises(VariableTableError, match=message) as info:
        table(tmp_path, body)
    assert "variables.yaml" in str(info.value)


def test_malformed_yaml_is_named(tmp_path):
    with pytest.raises(VariableTableError, match="malformed YAML"):
        table(tmp_path, "  - {name: [\n")


def test_a_table_without_a_sample_period_is_refused(tmp_path):
    with pytest.raises(VariableTableError, match="positive parameter 'sample_period' in s"):
        table(
            tmp_path, "  - {name: a, causality: input, unit: A, start: 0.0, description: x}\n", ""
        )


def test_families_and_dependencies_are_read(tmp_path):
    t = table(
        tmp_path,
        """
  - {name: u, causality: input, unit: A, start: 0.0, description: x}
  - {name: y, causality: output, unit: m, depends_on: [u], description: x}
  - {name: z, causality: output, unit: m, description: x}
  - {name: gain_2, causality: parameter, unit: "1", start: 2.0, description: x}
  - {name: gain_1, causality: parameter, unit: "1", start: 1.0, description: x}
""",
    )
    assert t.by_name("y").depends_on == ("u",)
    assert t.by_name("z").depends_on == ()
    assert [v.name for v in t.families()["gain"]] == ["gain_1", "gain_2"]
