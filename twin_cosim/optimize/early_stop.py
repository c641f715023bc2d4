"""Exact early stopping: stop a run once its fitness can no longer matter to the method.

E_pk is a running maximum of |x_ref - x|: once the error of a run exceeds a cutoff c (um), its
E_pk, and the fitness of its candidate, exceed c whatever follows. When the method cannot use a
value above c, the run stops there and the candidate is told a lower bound just above c; the
method decides exactly as it would with the full value. Where it is exact:

- **CE** (``ce``): a generation keeps only its elite, the ``ceil(rho N)`` best of N. Once that
  many candidates of the generation are known, the largest of their elite-many best values is a
  cutoff: a candidate above it cannot enter the elite nor become the best so far, and nothing
  else of the generation enters the update or the stop rules. The cutoff only falls as more
  candidates finish, so a cutoff taken when a candidate is sent out stays valid.
- **A guess** speeds the start of a CE generation up, before elite-many of its candidates are
  known: candidates go out with the cutoff known or :data:`GUESS_FACTOR` times the previous
  generation's cutoff, whichever is lower. A guess is no cutoff: once every candidate of the
  generation is answered, those stopped below the generation's cutoff run again with it (the
  cutoff known then), so the method is told exactly what it would be told without a guess. The
  cutoff is taken over the complete evaluations only: a lower bound is no value. A guess too
  low for every candidate (each stopped at it: nothing is known but that they are above it)
  leaves that second pass without a cutoff until its first complete evaluation; it goes out
  with a second guess, :data:`MISS_FACTOR` times the first, and a third pass, if one is
  needed, with none.
- **A worker's own evaluations**: on a local process pool a campaign keeps one candidate more
  out than it has workers, so a worker that finishes finds its next candidate waiting; that
  candidate's cutoff was taken before the command read the worker's last result. Any of the
  generation's complete values make a cutoff (a candidate above the elite-count-th best of some
  of them has that many better), so the worker lowers the cutoff by its own complete
  evaluations of the generation (:class:`OwnEvaluations`).
- **Over several runs** (robust objective): with the worst case over scenarios x samples, a
  candidate stops at its first run above the cutoff; with the mean over n runs, once the sum so
  far exceeds n c (every run adds >= 0).

Where it is not exact, it is off: CMA-ES and the GA rank every candidate, SA accepts by the
value of the difference, scipy's DE keeps every member's value for its convergence test; and
an objective window that does not span the whole run (errors outside the window do not count
in E_pk but would stop the run).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from twin_cosim.optimize.algorithms.base import ceil_count
from twin_cosim.optimize.worker_specs import EvaluationTask

EXACT_METHODS = ("ce",)

# The guess of a generation's cutoff: this many times the previous generation's. It changes the
# cost only (a candidate stopped below the cutoff the generation ends with runs again). Chosen
# by the simulated steps of the paper's CE campaign on reference 1, seeds 11-14, among 1.0, 1.2,
# 1.5, 2 and none: 0.72-0.88 times the steps of the same campaigns without a guess, the fewest.
GUESS_FACTOR = 1.2

# The guess of a generation's second pass: this many times the first pass's guess. It changes the
# cost only, like the first. Chosen by the simulated steps of the paper's CE campaign on
# reference 1 with 2 workers, seeds 12-20, among 1.3, 1.5, 2 and none (the second pass with the
# cutoff known then): 0.960, 0.952, 0.967 and 1 times the steps of none; seed 11, held out,
# 0.86 with 1.5.
MISS_FACTOR = 1.5


def window_spans_run(window: tuple[float, float | None], duration: float) -> bool:
    """Whether an objective window (t0, tF) in s covers a run of ``duration`` s."""
    t0, t_end = window
    return t0 <= 1e-12 and (t_end is None or t_end >= duration - 1e-9)


def elite_count(optimizer, batch_size: int) -> int:
    """How many complete values of a generation of ``batch_size`` make its cutoff: the CE elite
    count; 0 for a method where a cutoff is not exact."""
    if optimizer.name not in EXACT_METHODS:
        return 0
    return ceil_count(optimizer.settings.elite_fraction, batch_size)


def kth_best(values: np.ndarray | list[float], k: int) -> float:
    """The ``k``-th lowest of ``values`` (k >= 1), the cutoff they make; inf with fewer than
    ``k`` values or k = 0."""
    if k < 1 or len(values) < k:
        return math.inf
    return float(np.partition(np.asarray(values, dtype=np.float64), k - 1)[k - 1])


def elite_cutoff(optimizer, batch_size: int, known: np.ndarray) -> float:
    """The cutoff (fitness units) of a CE generation of ``batch_size`` given the values known.

    Returns inf while fewer than the elite count are known, or for a method where a cutoff is
    not exact.
    """
    return kth_best(known, elite_count(optimizer, batch_size))


def guess_above(cutoff: float) -> float:
    """The guess (fitness units) of the next generation's cutoff from this one's."""
    return GUESS_FACTOR * cutoff


def guess_after_miss(guess: float) -> float:
    """The guess (fitness units) of a generation's second pass, from its first pass's."""
    return MISS_FACTOR * guess


def lower_bound_above(cutoff: float) -> float:
    """The value told for a stopped candidate: the next float above the cutoff."""
    return float(np.nextafter(cutoff, math.inf))


class OwnEvaluations:
    """A worker's complete evaluations of the generation under way, which lower the cutoff of
    the generation's next candidate it runs (see the module's docstring).

    A task of another generation (its key differs) starts over; a task without a generation
    or elite count keeps its own cutoff.
    """

    def __init__(self) -> None:
        self._generation = ""
        self._values: list[float] = []

    def evaluate(
        self,
        task: EvaluationTask | np.ndarray,
        evaluate: Callable[[np.ndarray, float], dict[str, Any]],
    ) -> dict[str, Any]:
        """``evaluate(x, cutoff_um)`` of the task's candidate with the lower of its cutoff (um)
        and the one this worker's own complete evaluations of its generation make; a plain
        candidate (no task) has no cutoff.

        Returns
        -------
        dict
            The result of ``evaluate`` (its ``fitness``, um, and ``status``; ``stopped``: a
            lower bound, not a value).
        """
        if not isinstance(task, EvaluationTask):
            return evaluate(task, math.inf)
        if task.generation != self._generation:
            self._generation, self._values = task.generation, []
        own = kth_best(self._values, task.elite)  # none kept for a task without a generation
        result = evaluate(task.x, min(task.cutoff_um, own))
        if task.generation and result["status"] != "stopped":
            self._values.append(result["fitness"])
        return result
