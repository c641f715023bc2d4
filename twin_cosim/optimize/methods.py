"""The optimizer methods by short name: the one registry of their names.

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


def method_list() -> str:
    """The names for a message: ``ce, ga, sa, cmaes or de``."""
    return ", ".join(METHOD_NAMES[:-1]) + f" or {METHOD_NAMES[-1]}"
