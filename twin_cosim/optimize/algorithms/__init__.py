"""Batch ask/tell optimizers in the normalised unit box, and the registry of the methods by short
name: their names, the labels people read (``cmaes`` on the command line, ``CMA-ES`` in tables,
plots and messages) and their classes.

See ``docs/optimizers.md`` for the algorithms and the reading of the paper's Table 2.

Light to import (no numerical library): the command line lists the names without loading the
algorithms. Each algorithm's module is imported when it is first asked for
(:func:`make_optimizer`, or :data:`ALGORITHMS`, which imports them all): a CE campaign does not
load SciPy's optimizers or pycma.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

    from twin_cosim.optimize.algorithms.base import Optimizer

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

# Where each class lives: method name -> (module of this package, class name); each class's
# ``name`` is its key (tested).
_CLASSES = {
    "ce": ("paper_methods", "CrossEntropy"),
    "ga": ("paper_methods", "GeneticAlgorithm"),
    "sa": ("paper_methods", "SimulatedAnnealing"),
    "cmaes": ("cmaes", "CMAES"),
    "de": ("differential_evolution", "DifferentialEvolution"),
}


def method_label(method: str) -> str:
    """The name people read for a method key: ``cmaes`` -> ``CMA-ES``."""
    return LABELS.get(method, method)


def method_list() -> str:
    """The names for a message: ``ce, ga, sa, cmaes or de``."""
    return ", ".join(METHOD_NAMES[:-1]) + f" or {METHOD_NAMES[-1]}"


def method_settings(
    method: str,
    start: str | None,
    configured: dict[str, Any],
    given: dict[str, Any],
    budget: int | None,
) -> dict[str, Any]:
    """A campaign's settings of its method: ``configured`` (a scenario's
    ``optimize.methods.<method>``), ``given`` on top, then ``budget`` (None: the method's own).

    A campaign that refines a given ``start`` set has CMA-ES evaluate the start point with its
    first generation (``inject_start``), so the search ranks it with the others and never ends
    worse than where it started; the paper's methods keep their own start.
    """
    settings = {
        **({"inject_start": True} if start is not None and method == "cmaes" else {}),
        **configured,
        **given,
    }
    if budget is not None:
        settings["budget"] = budget
    return settings


def algorithm(name: str) -> type[Optimizer]:
    """The optimizer class registered as ``name`` (its module imported now).

    Raises
    ------
    ValueError
        On an unknown name (the message lists the valid ones).
    """
    try:
        module, cls = _CLASSES[name]
    except KeyError:
        raise ValueError(
            f"unknown optimizer {name!r}; valid names: {', '.join(METHOD_NAMES)}"
        ) from None
    return getattr(importlib.import_module(f"{__name__}.{module}"), cls)


def make_optimizer(
    name: str, dim: int, seed: int, x0: np.ndarray | None = None, **settings: Any
) -> Optimizer:
    """Instantiate the optimizer registered as ``name``.

    Parameters
    ----------
    name
        A method name of :data:`METHOD_NAMES`.
    dim, seed, x0, **settings
        Passed to the optimizer's constructor.

    Raises
    ------
    ValueError
        On an unknown name (the message lists the valid ones) or invalid settings.
    """
    return algorithm(name)(dim, seed, x0, **settings)


def __getattr__(attribute: str) -> Any:
    """``ALGORITHMS`` (every class by name, all imported) and ``Optimizer``, on first use."""
    if attribute == "ALGORITHMS":
        return {name: algorithm(name) for name in METHOD_NAMES}
    if attribute == "Optimizer":
        return importlib.import_module(f"{__name__}.base").Optimizer
    raise AttributeError(f"module {__name__!r} has no attribute {attribute!r}")


__all__ = [
    "ALGORITHMS",
    "LABELS",
    "METHODS",
    "METHOD_NAMES",
    "Optimizer",
    "algorithm",
    "make_optimizer",
    "method_label",
    "method_list",
    "method_settings",
]
