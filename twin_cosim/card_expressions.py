"""Arithmetic formulas of a plant-model card, checked when the card is read.

A formula is a Python arithmetic expression over

- bare names: the values it is given (a hypothesis' fitted parameters, or plant parameters);
- ``nominal.NAME``: a nominal plant parameter (the twin's value before an effect is added);
- ``context.NAME``: a value the diagnosis reads from the data (e.g. ``context.screw_order``);
- numbers, ``pi``, ``+ - * / **``, unary minus, and the functions ``abs``, ``sqrt``, ``exp``,
  ``cos``, ``sin``, ``hypot``, ``atan2`` and ``round``.

Nothing else parses (no attribute of anything else, no call of anything else), so a card is
data, never code. Each operation is the Python operation it reads as, in the order written, so
that a formula gives the same floating-point result as the same expression written in Python. A
division by zero gives +inf (a size relative to a nominal value of zero is unbounded).
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Mapping
from typing import Any

FUNCTIONS = {
    "abs": abs,
    "sqrt": math.sqrt,
    "exp": math.exp,
    "cos": math.cos,
    "sin": math.sin,
    "hypot": math.hypot,
    "atan2": math.atan2,
    "round": round,
}
CONSTANTS = {"pi": math.pi}
NAMESPACES = ("nominal", "context")
_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Pow: operator.pow,
}


class FormulaError(ValueError):
    """A formula does not parse, or uses a name or an operation a card may not use."""


class Formula:
    """One checked formula.

    Parameters
    ----------
    text
        The expression.
    names
        Bare names it may use.
    nominal
        Names it may use as ``nominal.NAME`` (none when empty).
    context
        Names it may use as ``context.NAME``; any name when None.
    """

    def __init__(
        self,
        text: str,
        names: tuple[str, ...] = (),
        nominal: frozenset[str] = frozenset(),
        context: frozenset[str] | None = frozenset(),
    ) -> None:
        self.text = str(text)
        self._names, self._nominal, self._context = set(names), nominal, context
        try:
            self._tree = ast.parse(self.text, mode="eval").body
        except SyntaxError as exc:
            raise FormulaError(f"{self.text!r}: not an arithmetic expression: {exc.msg}") from None
        self.uses: set[str] = set()
        self._check(self._tree)

    def __repr__(self) -> str:
        return f"Formula({self.text!r})"

    def _check(self, node: ast.AST) -> None:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise FormulaError(f"{self.text!r}: {node.value!r} is not a number")
        elif isinstance(node, ast.Name):
            if node.id not in self._names and node.id not in CONSTANTS:
                raise FormulaError(
                    f"{self.text!r}: unknown name {node.id!r}; expected one of "
                    f"{sorted(self._names | set(CONSTANTS))}, nominal.NAME or context.NAME"
                )
            self.uses.add(node.id)
        elif isinstance(node, ast.Attribute):
            self._check_attribute(node)
        elif isinstance(node, ast.BinOp) and type(node.op) in (*_BINARY, ast.Div):
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            self._check(node.operand)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            if node.func.id not in FUNCTIONS or node.keywords:
                raise FormulaError(
                    f"{self.text!r}: {node.func.id}(...) is not one of {sorted(FUNCTIONS)}"
                )
            for argument in node.args:
                self._check(argument)
        else:
            raise FormulaError(f"{self.text!r}: {ast.unparse(node)!r} is not allowed in a formula")

    def _check_attribute(self, node: ast.Attribute) -> None:
        space = node.value.id if isinstance(node.value, ast.Name) else None
        if space not in NAMESPACES:
            raise FormulaError(f"{self.text!r}: only nominal.NAME and context.NAME are allowed")
        allowed = self._nominal if space == "nominal" else self._context
        if allowed is not None and node.attr not in allowed:
            raise FormulaError(f"{self.text!r}: {space}.{node.attr} is not known to this card")

    def __call__(
        self,
        values: Mapping[str, Any],
        nominal: Mapping[str, float] | None = None,
        context: Mapping[str, float] | None = None,
    ) -> Any:
        """The formula's value for the given names (``nominal``, ``context``: the namespaces)."""
        spaces = {"nominal": nominal or {}, "context": context or {}}
        return _evaluate(self._tree, values, spaces)


def _evaluate(node: ast.AST, values: Mapping[str, Any], spaces: dict[str, Mapping]) -> Any:
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        return CONSTANTS[node.id] if node.id in CONSTANTS else values[node.id]
    if isinstance(node, ast.Attribute):
        return spaces[node.value.id][node.attr]
    if isinstance(node, ast.BinOp):
        left = _evaluate(node.left, values, spaces)
        right = _evaluate(node.right, values, spaces)
        if isinstance(node.op, ast.Div):
            return math.inf if right == 0 else left / right
        return _BINARY[type(node.op)](left, right)
    if isinstance(node, ast.UnaryOp):
        operand = _evaluate(node.operand, values, spaces)
        return -operand if isinstance(node.op, ast.USub) else +operand
    arguments = [_evaluate(a, values, spaces) for a in node.args]
    return FUNCTIONS[node.func.id](*arguments)
