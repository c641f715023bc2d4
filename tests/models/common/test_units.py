"""models/common/units.yaml against dimensional analysis: each unit's SI base-unit exponents are
computed from its name (products '.', one quotient '/', powers as trailing integers) and must
equal the table's."""

from __future__ import annotations

import re
from collections import Counter

import pytest
import yaml

from fmu_build.build import COMMON_DIR, MODELS_DIR
from fmu_build.variable_table import load_variable_table

# Symbols in SI base units (kg, m, s, A) plus the radian, which FMI keeps as a base unit.
SYMBOLS: dict[str, dict[str, int]] = {
    "1": {},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "s": {"s": 1},
    "A": {"A": 1},
    "rad": {"rad": 1},
    "Hz": {"s": -1},
    "N": {"kg": 1, "m": 1, "s": -2},  # N = kg.m/s2
    "J": {"kg": 1, "m": 2, "s": -2},  # J = N.m
    "W": {"kg": 1, "m": 2, "s": -3},  # W = J/s
    "V": {"kg": 1, "m": 2, "s": -3, "A": -1},  # V = W/A
}
FACTOR = re.compile(r"^(?P<symbol>[A-Za-z]+|1)(?P<power>-?\d+)?$")


def dimensions(name: str) -> dict[str, int]:
    """Base-unit exponents of a unit name such as ``N.m.s/rad``, ``kg.m2`` or ``1/s``."""
    numerator, _, denominator = name.partition("/")
    total: Counter[str] = Counter()
    for part, sign in ((numerator, 1), (denominator, -1)):
        if not part:
            continue
        for factor in part.split("."):
            match = FACTOR.match(factor)
            assert match and match["symbol"] in SYMBOLS, f"cannot read unit factor {factor!r}"
            power = int(match["power"] or 1)
            for base, exponent in SYMBOLS[match["symbol"]].items():
                total[base] += sign * power * exponent
    return {base: exponent for base, exponent in total.items() if exponent != 0}


UNITS = yaml.safe_load((COMMON_DIR / "units.yaml").read_text())


@pytest.mark.parametrize("unit", sorted(UNITS))
def test_base_units_follow_from_the_name(unit):
    assert UNITS[unit] == dimensions(unit)


def test_the_dimension_rules_know_their_units():
    assert dimensions("N/V") == {"m": -1, "s": 1, "A": 1}
    assert dimensions("N.m/A") == dimensions("V.s")
    assert dimensions("kg.m2") == {"kg": 1, "m": 2}


@pytest.mark.parametrize("model", ["drive2mass", "emps"])
def test_every_unit_a_model_uses_is_checked(model):
    table = load_variable_table(MODELS_DIR / model / "variables.yaml", COMMON_DIR / "units.yaml")
    for unit in {v.unit for v in table.variables}:
        assert table.units[unit] == dimensions(unit), unit
