"""Batch ask/tell optimizers in the normalised unit box, and a registry by short name.

See ``docs/optimizers.md`` for the algorithms and the reading of the paper's Table 2.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from twin_cosim.optimize.algorithms.annealing import AnnealingSettings, SimulatedAnnealing
from twin_cosim.optimize.algorithms.base import Optimizer
from twin_cosim.optimize.algorithms.cmaes import CMAES, CMAESSettings
from twin_cosim.optimize.algorithms.cross_entropy import CrossEntropy, CrossEntropySettings
from twin_cosim.optimize.algorithms.differential_evolution import (
    DifferentialEvolution,
    DifferentialEvolutionSettings,
)
from twin_cosim.optimize.algorithms.genetic import GeneticAlgorithm, GeneticSettings
from twin_cosim.optimize.methods import METHOD_NAMES

_CLASSES = (CrossEntropy, GeneticAlgorithm, SimulatedAnnealing, CMAES, DifferentialEvolution)
_BY_NAME = {cls.name: cls for cls in _CLASSES}
ALGORITHMS: dict[str, type[Optimizer]] = {name: _BY_NAME[name] for name in METHOD_NAMES}


def make_optimizer(
    name: str, dim: int, seed: int, x0: np.ndarray | None = None, **settings: Any
) -> Optimizer:
    """Instantiate the optimizer registered as ``name``.

    Parameters
    ----------
    name
        A key of :data:`ALGORITHMS`.
    dim, seed, x0, **settings
        Passed to the optimizer's constructor.

    Raises
    ------
    ValueError
        On an unknown name (the message lists the valid ones) or invalid settings.
    """
    try:
        cls = ALGORITHMS[name]
    except KeyError:
        raise ValueError(
            f"unknown optimizer {name!r}; valid names: {', '.join(ALGORITHMS)}"
        ) from None
    return cls(dim, seed, x0, **settings)


__all__ = [
    "ALGORITHMS",
    "CMAES",
    "AnnealingSettings",
    "CMAESSettings",
    "CrossEntropy",
    "CrossEntropySettings",
    "DifferentialEvolution",
    "DifferentialEvolutionSettings",
    "GeneticAlgorithm",
    "GeneticSettings",
    "Optimizer",
    "SimulatedAnnealing",
    "make_optimizer",
]
