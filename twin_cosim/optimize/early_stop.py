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
  cutoff is taken over the complete evaluations only: a lower bound is no value.
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

import numpy as np

from twin_cosim.optimize.algorithms.base import ceil_count

EXACT_METHODS = ("ce",)

# The guess of a generation's cutoff: this many times the previous generation's. It changes the
# cost only (a candidate stopped below the cutoff the generation ends with runs again). Chosen
# by the simulated steps of the paper's CE campaign on reference 1, seeds 11-14, among 1.0, 1.2,
# 1.5, 2 and none: 0.72-0.88 times the steps of the same campaigns without a guess, the fewest.
GUESS_FACTOR = 1.2


def window_spans_run(window: tuple[float, float | None], duration: float) -> bool:
    """Whether an objective window (t0, tF) in s covers a run of ``duration`` s."""
    t0, t_end = window
    return t0 <= 1e-12 and (t_end is None or t_end >= duration - 1e-9)


def elite_cutoff(optimizer, batch_size: int, known: np.ndarray) -> float:
    """The cutoff (fitness units) of a CE generation of ``batch_size`` given the values known.

    Returns inf while fewer than the elite count are known, or for a method where a cutoff is
    not exact.
    """
    if optimizer.name not in EXACT_METHODS:
        return math.inf
    n_elite = ceil_count(optimizer.settings.elite_fraction, batch_size)
    if len(known) < n_elite:
        return math.inf
    return float(np.partition(np.asarray(known, dtype=np.float64), n_elite - 1)[n_elite - 1])


def guess_above(cutoff: float) -> float:
    """The guess (fitness units) of the next generation's cutoff from this one's."""
    return GUESS_FACTOR * cutoff


def lower_bound_above(cutoff: float) -> float:
    """The value told for a stopped candidate: the next float above the cutoff."""
    return float(np.nextafter(cutoff, math.inf))
