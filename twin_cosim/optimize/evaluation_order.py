"""The order a generation's candidates go out in under exact early stopping: likeliest best first.

With exact early stopping (:mod:`twin_cosim.optimize.early_stop`) a candidate runs to the end
only while its error stays under the cutoff, and the cutoff falls as good candidates finish: the
sooner the generation's best is known, the sooner the others stop. Each candidate's fitness is
predicted from the complete evaluations logged so far (the geometric mean of its
:data:`NEIGHBOURS` nearest, in the unit cube) and the candidates go out in that order. The order
changes the cost only, never what the method is told. Chosen by the simulated steps of the
paper's CE campaign on reference 1, seeds 11-14 (two runs each), against the order the method
asked in: 0.89-0.98 times the steps with 3 neighbours, 0.92-1.01 with 1.
"""

from __future__ import annotations

import numpy as np

NEIGHBOURS = 3


def likeliest_best_first(
    candidates: np.ndarray, evaluated: np.ndarray, fitness: np.ndarray
) -> np.ndarray:
    """The order (indices into ``candidates``) from the lowest predicted fitness up.

    Parameters
    ----------
    candidates
        The candidates, one per row, in the unit cube.
    evaluated
        Complete evaluations logged so far, one per row, in the unit cube.
    fitness
        Their fitness (um, > 0), one per row of ``evaluated``.

    Returns
    -------
    numpy.ndarray
        Indices into ``candidates``; the order asked in (``arange``) while nothing is
        evaluated, and among equal predictions.
    """
    if len(evaluated) == 0:
        return np.arange(len(candidates))
    squared = ((candidates[:, None, :] - evaluated[None, :, :]) ** 2).sum(axis=-1)
    nearest = np.argsort(squared, axis=1, kind="stable")[:, :NEIGHBOURS]
    predicted = np.log(fitness[nearest]).mean(axis=1)
    return np.argsort(predicted, kind="stable")
