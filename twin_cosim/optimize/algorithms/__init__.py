"""Batch ask/tell optimizers in the normalised unit box, and a registry by short name.

See ``docs/optimizers.md`` for the algorithms and the reading of the paper's Table 2.

Each algorithm's module is imported when it is first asked for (:func:`make_optimizer`, or
:data:`ALGORITHMS`, which imports them all): a CE campaign does not load SciPy's optimizers or
pycma.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from twin_cosim.optimize.methods import METHOD_NAMES

if TYPE_CHECKING:
    import numpy as np

    from twin_cosim.optimize.algorithms.base import Optimizer

# Where each class lives: method name -> (module of this package, class name).
_CLASSES = {
    "ce": ("cross_entropy", "CrossEntropy"),
    "ga": ("genetic", "GeneticAlgorithm"),
    "sa": ("annealing", "SimulatedAnnealing"),
    "cmaes": ("cmaes", "CMAES"),
    "de": ("differential_evolution", "DifferentialEvolution"),
}


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
        A method name of :data:`~twin_cosim.optimize.methods.METHOD_NAMES`.
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


__all__ = ["ALGORITHMS", "Optimizer", "algorithm", "make_optimizer"]
