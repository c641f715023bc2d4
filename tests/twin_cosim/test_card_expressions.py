"""Card formulas: the same floating-point result as the Python expression, and nothing but
arithmetic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin_cosim.card_expressions import Formula, FormulaError


@pytest.mark.parametrize(
    ("text", "python"),
    [
        ("a + b * c - a / c", lambda a, b, c: a + b * c - a / c),
        ("hypot(a, b)", lambda a, b, c: math.hypot(a, b)),
        ("atan2(-b, a) + pi / 2", lambda a, b, c: math.atan2(-b, a) + math.pi / 2),
        ("c / sqrt(1.0 + a)", lambda a, b, c: c / math.sqrt(1.0 + a)),
        ("abs(sqrt(1.0 + a) - 1.0)", lambda a, b, c: abs(math.sqrt(1.0 + a) - 1.0)),
        ("b * c ** 2", lambda a, b, c: b * c**2),
    ],
)
def test_a_formula_computes_what_python_computes_bit_for_bit(text, python):
    formula = Formula(text, ("a", "b", "c"))
    rng = np.random.default_rng(3)
    for a, b, c in rng.uniform(0.1, 3.0, size=(50, 3)):
        assert formula({"a": a, "b": b, "c": c}) == python(a, b, c)


def test_nominal_and_context_are_their_own_namespaces():
    formula = Formula(
        "nominal.backlash + delta", ("delta",), frozenset({"backlash"}), frozenset({"order"})
    )
    assert formula({"delta": 1e-6}, {"backlash": 12.2e-6}) == 12.2e-6 + 1e-6
    order = Formula("context.order", (), frozenset(), frozenset({"order"}))
    assert order({}, {}, {"order": 6.0}) == 6.0


def test_a_division_by_zero_is_unbounded():
    assert Formula("abs(d) / n", ("d", "n"))({"d": 1e-6, "n": 0.0}) == math.inf


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x.__class__", "only nominal.NAME and context.NAME"),
        ("open('f')", "is not one of"),
        ("nominal.no_such", "nominal.no_such is not known"),
        ("y + 1", "unknown name 'y'"),
        ("'text'", "is not a number"),
        ("x if x else 1", "is not allowed"),
        ("[x]", "is not allowed"),
        ("x +", "not an arithmetic expression"),
        ("abs(x, key=1)", "is not one of"),
    ],
)
def test_anything_but_arithmetic_is_refused(text, message):
    with pytest.raises(FormulaError, match=message.replace("(", r"\(")):
        Formula(text, ("x",), frozenset({"backlash"}))
