"""The declarative variable table of a model (``models/<name>/variables.yaml``), loaded and checked.

The table is the single source from which the C variable table and ``modelDescription.xml`` are
generated. Value references are assigned densely in table order: Real variables first, then
Integer variables.

Facts that the table holds for the generator as well as for the C code:

- ``depends_on`` of an output: the inputs it depends on directly (ModelStructure dependencies);
  an output without it depends on no input (it follows from the state alone).
- the parameter ``sample_period`` (s): its start value is the DefaultExperiment step size.
- families: variables named ``<base>_1 ... <base>_n`` form a family of n entries (e.g. the
  noise harmonics); the generator emits their count and offsets for the C code.
- ``time`` is no variable of the table: it is the independent variable that FMI 3.0 declares,
  with the first value reference after the table's.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

CAUSALITIES = ("parameter", "input", "output")
TYPES = ("Real", "Integer")
VARIABLE_KEYS = {
    "name",
    "causality",
    "type",
    "unit",
    "start",
    "min",
    "max",
    "positive",
    "description",
    "depends_on",
}
MODEL_KEYS = {"name", "description", "version"}
STEP_PARAMETER = "sample_period"
TIME = "time"  # FMI 3.0's independent variable, declared by the generator
FAMILY_NAME = re.compile(r"^(?P<base>[A-Za-z_]\w*?)_(?P<index>[1-9]\d*)$")


class VariableTableError(ValueError):
    """A variable table or unit table is malformed; the message names the file and the entry."""


@dataclass(frozen=True)
class Variable:
    """One model variable as declared in the table."""

    name: str
    causality: str
    type: str
    unit: str
    start: float | int | None
    min: float | int | None
    max: float | int | None
    positive: bool
    description: str
    value_reference: int
    depends_on: tuple[str, ...] = ()


@dataclass(frozen=True)
class VariableTable:
    """A model's identity, its variables (in value-reference order) and the unit definitions."""

    name: str
    description: str
    version: str
    variables: tuple[Variable, ...]
    units: dict[str, dict[str, int]]
    source: Path

    def of_type(self, type_name: str) -> list[Variable]:
        """Variables of one FMI base type, in value-reference order."""
        return [v for v in self.variables if v.type == type_name]

    def by_name(self, name: str) -> Variable:
        """The variable called ``name``; KeyError names the table when there is none."""
        for v in self.variables:
            if v.name == name:
                return v
        raise KeyError(f"{self.source}: no variable named {name!r}")

    @property
    def default_step_size(self) -> float:
        """Default communication step (s): the start value of the ``sample_period`` parameter."""
        return float(self.by_name(STEP_PARAMETER).start)

    @property
    def time_value_reference(self) -> int:
        """Value reference of the independent variable ``time`` of FMI 3.0: the first after the
        table's (the C slave reads the model time for it)."""
        return len(self.variables)

    def families(self) -> dict[str, list[Variable]]:
        """Variables named ``<base>_1 ... <base>_n`` by base name, in index order."""
        return _families(self.source, self.variables)


def _families(path: Path, variables: tuple[Variable, ...]) -> dict[str, list[Variable]]:
    indexed: dict[str, dict[int, Variable]] = {}
    for v in variables:
        match = FAMILY_NAME.match(v.name)
        if match:
            indexed.setdefault(match["base"], {})[int(match["index"])] = v
    families = {}
    for base, members in indexed.items():
        if sorted(members) != list(range(1, len(members) + 1)):
            raise VariableTableError(
                f"{path}: variables {base}_k must be numbered 1 to n without gaps, "
                f"got k = {sorted(members)}"
            )
        if any(m.type != "Real" for m in members.values()):
            raise VariableTableError(f"{path}: variables {base}_k must all be Real")
        families[base] = [members[k] for k in sorted(members)]
    return families


def _load_yaml(path: Path) -> Any:
    try:
        # libyaml's parser where PyYAML has it (ten times faster), else PyYAML's own
        loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
        return yaml.load(path.read_text(), Loader=loader)  # noqa: S506 - a safe loader
    except FileNotFoundError as exc:
        raise VariableTableError(f"{path}: file not found") from exc
    except yaml.YAMLError as exc:
        raise VariableTableError(f"{path}: malformed YAML: {exc}") from exc


def load_units(path: Path) -> dict[str, dict[str, int]]:
    """Load the shared unit table: unit name -> SI base-unit exponents."""
    data = _load_yaml(path)
    if not isinstance(data, dict):
        raise VariableTableError(f"{path}: expected a mapping of unit name to base-unit exponents")
    allowed = {"kg", "m", "s", "A", "K", "mol", "cd", "rad"}
    for unit, exponents in data.items():
        if not isinstance(exponents, dict) or not set(exponents) <= allowed:
            raise VariableTableError(
                f"{path}: unit {unit!r} must map base units {sorted(allowed)} to integer exponents"
            )
    return {str(k): dict(v) for k, v in data.items()}


def _check_number(path: Path, name: str, key: str, value: Any, type_name: str) -> None:
    if type_name == "Integer":
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = (
            isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        )
    if not ok:
        expected = "an integer" if type_name == "Integer" else "a finite number"
        raise VariableTableError(
            f"{path}: variable {name!r}: {key} must be {expected}, got {value!r}"
        )


def _parse_variable(path: Path, entry: Any, units: dict[str, dict[str, int]]) -> dict[str, Any]:
    if not isinstance(entry, dict) or "name" not in entry:
        raise VariableTableError(f"{path}: every variable must be a mapping with a 'name'")
    name = entry["name"]
    unknown = set(entry) - VARIABLE_KEYS
    if unknown:
        raise VariableTableError(
            f"{path}: variable {name!r}: unknown keys {sorted(unknown)}; "
            f"allowed {sorted(VARIABLE_KEYS)}"
        )
    causality = entry.get("causality")
    if causality not in CAUSALITIES:
        raise VariableTableError(
            f"{path}: variable {name!r}: causality must be one of {CAUSALITIES}"
        )
    type_name = entry.get("type", "Real")
    if type_name not in TYPES:
        raise VariableTableError(f"{path}: variable {name!r}: type must be one of {TYPES}")
    unit = str(entry.get("unit", "1"))
    if unit not in units:
        raise VariableTableError(
            f"{path}: variable {name!r}: unit {unit!r} is not in the unit table"
        )
    if causality == "output":
        if "start" in entry:
            raise VariableTableError(f"{path}: variable {name!r}: an output takes no start value")
    elif "start" not in entry:
        raise VariableTableError(f"{path}: variable {name!r}: a {causality} needs a start value")
    for key in ("start", "min", "max"):
        if key in entry:
            _check_number(path, name, key, entry[key], type_name)
    lo, hi, start = entry.get("min"), entry.get("max"), entry.get("start")
    if start is not None and ((lo is not None and start < lo) or (hi is not None and start > hi)):
        raise VariableTableError(f"{path}: variable {name!r}: start {start} outside [{lo}, {hi}]")
    if entry.get("positive") and start is not None and start <= 0:
        raise VariableTableError(f"{path}: variable {name!r}: positive, but start is {start}")
    if not entry.get("description"):
        raise VariableTableError(f"{path}: variable {name!r}: a description is required")
    depends_on = entry.get("depends_on", [])
    if causality != "output" and "depends_on" in entry:
        raise VariableTableError(f"{path}: variable {name!r}: only an output takes depends_on")
    if not isinstance(depends_on, list) or not all(isinstance(d, str) for d in depends_on):
        raise VariableTableError(
            f"{path}: variable {name!r}: depends_on must be a list of input names"
        )
    return {
        "name": name,
        "causality": causality,
        "type": type_name,
        "unit": unit,
        "start": start,
        "min": lo,
        "max": hi,
        "positive": bool(entry.get("positive", False)),
        "description": str(entry["description"]),
        "depends_on": tuple(depends_on),
    }


def load_variable_table(path: Path, units_path: Path) -> VariableTable:
    """Load and check a model's variable table.

    Parameters
    ----------
    path
        ``models/<name>/variables.yaml``.
    units_path
        The shared unit table ``models/common/units.yaml``.

    Raises
    ------
    VariableTableError
        On malformed YAML, unknown keys, missing fields, duplicate names or inconsistent limits.
    """
    units = load_units(units_path)
    data = _load_yaml(path)
    if not isinstance(data, dict) or set(data) != {"model", "variables"}:
        raise VariableTableError(
            f"{path}: expected exactly the top-level keys 'model' and 'variables'"
        )
    model = data["model"]
    if not isinstance(model, dict) or set(model) != MODEL_KEYS:
        raise VariableTableError(f"{path}: 'model' must have exactly the keys {sorted(MODEL_KEYS)}")
    if not str(model["name"]).isidentifier():
        raise VariableTableError(f"{path}: model.name must be a C identifier")
    parsed = [_parse_variable(path, entry, units) for entry in data["variables"] or []]
    names = [p["name"] for p in parsed]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise VariableTableError(f"{path}: duplicate variable names {duplicates}")
    for name in names:
        if not name.isidentifier():
            raise VariableTableError(f"{path}: variable name {name!r} must be a C identifier")
    if TIME in names:
        raise VariableTableError(
            f"{path}: the name {TIME!r} is reserved for the independent variable of FMI 3.0, "
            "which the generator declares"
        )
    inputs = {p["name"] for p in parsed if p["causality"] == "input"}
    for p in parsed:
        unknown_inputs = sorted(set(p["depends_on"]) - inputs)
        if unknown_inputs:
            raise VariableTableError(
                f"{path}: variable {p['name']!r}: depends_on names {unknown_inputs}, "
                f"which are not inputs; inputs are {sorted(inputs)}"
            )
    step = next((p for p in parsed if p["name"] == STEP_PARAMETER), None)
    if (
        step is None
        or step["causality"] != "parameter"
        or step["unit"] != "s"
        or not step["positive"]
    ):
        raise VariableTableError(
            f"{path}: expected a positive parameter {STEP_PARAMETER!r} in s (the drive's sample "
            "period, whose start value is the default communication step)"
        )
    ordered = [p for p in parsed if p["type"] == "Real"] + [
        p for p in parsed if p["type"] != "Real"
    ]
    variables = tuple(Variable(value_reference=i, **p) for i, p in enumerate(ordered))
    _families(path, variables)
    return VariableTable(
        name=str(model["name"]),
        description=str(model["description"]),
        version=str(model["version"]),
        variables=variables,
        units=units,
        source=path,
    )
