"""The optimizer methods by short name: the one registry of their names and of the labels
tables, plots and messages give them (``cmaes`` on the command line, ``CMA-ES`` to read).

Light to import (no numerical library), so that the command line lists the names without loading
the algorithms; :data:`twin_cosim.optimize.algorithms.ALGORITHMS` maps the same names to the
classes (each class's ``name`` is its key; tested).
"""

from __future__ import annotations

METHODS: dict[str, str] = {
    "ce": "cross-entropy method (paper, Table 2)",
    "ga": "genetic algorithm (paper, Table 2)",
    "sa": "simulated annealing (paper, Table 2)",
    "cmaes": "CMA-ES (pycma), baseline",
    "de": "differential evolution (scipy), baseline",
}
METHOD_NAMES = tuple(METHODS)
# How tables, plots and messages name each method (the keys above stay the command line's)
LABELS: dict[str, str] = {"ce": "CE", "ga": "GA", "sa": "SA", "cmaes": "CMA-ES", "de": "DE"}


def method_label(method: str) -> str:
    """The name people read for a method key: ``cmaes`` -> ``CMA-ES``."""
    return LABELS.get(method, method)


def method_list() -> str:
    """The names for a message: ``ce, ga, sa, cmaes or de``."""
    return ", ".join(METHOD_NAMES[:-1]) + f" or {METHOD_NAMES[-1]}"


def refinement_settings(method: str, start: str | None) -> dict[str, bool]:
    """Settings a campaign adds when it refines a given start set (``--start``): CMA-ES then
    evaluates the start point with its first generation (``inject_start``), so the search ranks
    it with the others and never ends worse than where it started. The paper's methods keep
    their own start."""
    return {"inject_start": True} if start is not None and method == "cmaes" else {}
