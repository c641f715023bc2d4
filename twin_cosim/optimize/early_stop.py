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
  needed, with none (:meth:`EarlyStop.passes`).
- **The order** a generation goes out in: the likeliest best first. The sooner the
  generation's best is known, the sooner the others stop: each candidate's fitness is predicted
  from the complete evaluations logged so far (the geometric mean of its :data:`NEIGHBOURS`
  nearest, in the unit cube) and the candidates go out in that order
  (:func:`likeliest_best_first`). Chosen by the simulated steps of the paper's CE campaign on
  reference 1, seeds 11-14 (two runs each), against the order the method asked in: 0.89-0.98
  times the steps with 3 neighbours, 0.92-1.01 with 1.
- **A worker's own evaluations**: a generation's candidates go out one at a time, and on a local
  process pool one more than there are workers, so a worker that finishes finds its next
  candidate waiting (``Evaluator.ahead``); that candidate's cutoff was taken before the command
  read the worker's last result. Any of the generation's complete values make a cutoff (a
  candidate above the elite-count-th best of some of them has that many better), so the worker
  lowers the cutoff by its own complete evaluations of the generation (:class:`OwnEvaluations`;
  a task carries its generation's key and elite count, :class:`EvaluationTask`).
- **Over several runs** (several cases: a robust objective, a machine's circles): with the worst
  case, a candidate stops at its first run above the cutoff; with the mean over n runs, once the
  sum so far exceeds n c (every run adds >= 0) (:func:`least_fitness`, :func:`allowance`). The
  cases run in an order that puts first the case that stopped, or was the worst of, the
  previous candidate (:class:`CaseOrder`): cheaper stops.

A stopped candidate's lower bound is reused from the campaign's log only within its own
generation (elsewhere it is evaluated again). Each of the order, the guesses and the case order
changes the cost only, never what the method is told.

Where it is not exact, it is off: CMA-ES and the GA rank every candidate, SA accepts by the
value of the difference, scipy's DE keeps every member's value for its convergence test; and
an objective whose cutoff is not exact (a single axis' objective window that does not span the
whole run: errors outside the window do not count in E_pk but would stop the run). Without
early stopping a generation goes out at once, every candidate run to its end.
"""

from __future__ import annotations

import math
import secrets
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from twin_cosim.optimize.algorithms.base import ceil_count

if TYPE_CHECKING:
    from twin_cosim.optimize.algorithms.base import Optimizer
    from twin_cosim.optimize.config import OptimizeConfig
    from twin_cosim.optimize.store import EvaluationLog

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

# The complete evaluations nearest to a candidate that predict its fitness (the order).
NEIGHBOURS = 3


@dataclass(frozen=True)
class EvaluationTask:
    """A candidate, the cutoff (um) of its fitness, and the generation it belongs to.

    Attributes
    ----------
    x : numpy.ndarray
        The candidate, physical units (the problem's dimensions in order).
    cutoff_um : float
        The cutoff known when the task was sent, um (inf: none).
    generation : str
        The generation's key, unique across the campaigns a pool runs ("": none).
    elite : int
        The generation's elite count: that many of its complete values make a cutoff (0: no
        cutoff). A worker lowers the cutoff by its own complete evaluations of the generation
        (:class:`OwnEvaluations`).
    """

    x: np.ndarray
    cutoff_um: float = math.inf
    generation: str = ""
    elite: int = 0


def window_spans_run(window: tuple[float, float | None], duration: float) -> bool:
    """Whether an objective window (t0, tF) in s covers a run of ``duration`` s."""
    t0, t_end = window
    return t0 <= 1e-12 and (t_end is None or t_end >= duration - 1e-9)


def elite_count(optimizer: Optimizer, batch_size: int) -> int:
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


def elite_cutoff(optimizer: Optimizer, batch_size: int, known: np.ndarray) -> float:
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


def least_fitness(scores: Iterable[float], count: int, aggregate: str) -> float:
    """The least fitness (um) a candidate of ``count`` runs can end with, given the scores of
    some of them: the worst so far (``worst``), or their sum over ``count`` (``mean``: every run
    adds >= 0)."""
    scores = list(scores)
    return max(scores) if aggregate == "worst" else sum(scores) / count


def allowance(cutoff: float, scores: Iterable[float], count: int, aggregate: str) -> float:
    """The most (um) the next run of a candidate of ``count`` runs may score before its fitness
    is certain to exceed ``cutoff``, given the scores of the runs before it."""
    return cutoff if aggregate == "worst" else count * cutoff - sum(scores)


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


class GenerationValues:
    """What is known of a generation's candidates while it is evaluated.

    Attributes
    ----------
    fitness : numpy.ndarray
        Each candidate's fitness (um) once known.
    bound : numpy.ndarray
        Whether that fitness is a stopped candidate's lower bound, not a value.
    known : list of int
        The candidates known so far.
    """

    def __init__(self, count: int) -> None:
        self.fitness = np.empty(count)
        self.bound = np.zeros(count, dtype=bool)
        self.known: list[int] = []

    def set(self, rows: list[int], result: dict[str, Any]) -> None:
        """``rows`` (one candidate's) are known: a result's fitness (um) and status."""
        self.fitness[rows] = result["fitness"]
        self.bound[rows] = result["status"] == "stopped"
        self.known.extend(rows)


class EarlyStop:
    """A campaign's exact early stopping, generation after generation: the cutoffs, their
    guesses, the passes of a generation and the order its candidates go out in.

    Parameters
    ----------
    optimizer
        The campaign's optimizer.
    on
        Early stopping is on (the method and the objective allow it, and it was not turned off);
        off, every candidate of a generation goes out at once and runs to its end.
    """

    def __init__(self, optimizer: Optimizer, on: bool) -> None:
        self.optimizer = optimizer
        self.on = on
        self.guess = math.inf  # the guess of the next generation's cutoff (um)
        self.key = secrets.token_hex(8)  # with the generation's number: its key for the workers

    def cutoff(self, values: GenerationValues) -> float:
        """The generation's cutoff from the values known (um; inf when off): from the complete
        evaluations only (a lower bound is no value)."""
        if not self.on:
            return math.inf
        complete = [i for i in values.known if not values.bound[i]]
        return elite_cutoff(self.optimizer, len(values.fitness), values.fitness[complete])

    def passes(
        self, values: GenerationValues, missing: list[int]
    ) -> Iterator[tuple[list[int], float, bool]]:
        """The passes of a generation whose ``missing`` candidates are not known yet: each
        ``(rows, guess, again)``, the rows to evaluate now with cutoffs at most ``guess`` (um);
        ``again``: they were answered before (stopped below the generation's cutoff).

        The caller evaluates each pass's rows into ``values`` before asking for the next. The
        first pass has the guess from the previous generation; once every candidate is answered,
        those stopped below the generation's cutoff (where the guess was too low) run again with
        the cutoff known then, lowered to a second guess (a third pass has none).
        """
        guess, again = self.guess, False
        while True:
            if missing:
                yield missing, guess, again
            cutoff = self.cutoff(values)
            count = len(values.fitness)
            missing = [i for i in range(count) if values.bound[i] and values.fitness[i] <= cutoff]
            if not missing:
                break
            values.known = [i for i in values.known if i not in missing]
            guess = math.inf if again else guess_after_miss(guess)
            again = True
        self.guess = guess_above(cutoff)

    def order(
        self, candidates: np.ndarray, log: EvaluationLog, config: OptimizeConfig
    ) -> np.ndarray:
        """The order of ``candidates`` (physical units) to send them in: by the fitness the
        log's complete evaluations predict when on (:func:`likeliest_best_first`), else as
        asked."""
        if not self.on:
            return np.arange(len(candidates))
        complete = [e for e in log.entries if e["status"] != "stopped"]
        evaluated = np.array([e["x"] for e in complete], dtype=np.float64).reshape(
            len(complete), candidates.shape[1]
        )
        return likeliest_best_first(
            config.to_unit(candidates),
            config.to_unit(evaluated),
            np.array([e["fitness"] for e in complete]),
        )

    def tasks(
        self, candidates: np.ndarray, values: GenerationValues, guess: float
    ) -> Iterator[EvaluationTask]:
        """The tasks of ``candidates`` (rows of the generation), each with the cutoff known when
        it goes out, at most ``guess`` (um), and the generation's key and elite count (by which
        a worker lowers that cutoff with its own complete evaluations of the generation)."""
        generation = f"{self.key}:{self.optimizer.generation}"
        elite = elite_count(self.optimizer, len(values.fitness)) if self.on else 0
        for x in candidates:
            yield EvaluationTask(x, min(self.cutoff(values), guess), generation, elite)

    def in_flight(self, workers: int, ahead: int) -> int | None:
        """Tasks out at a time on an evaluator of ``workers`` that keeps ``ahead`` more waiting:
        that many when on, else the whole generation at once (None)."""
        return workers + ahead if self.on else None


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


class CaseOrder:
    """The order a worker runs a candidate's cases in: the case that stopped, or was the worst
    of, the previous candidate first (the likeliest to stop the next one early)."""

    def __init__(self, count: int) -> None:
        self._order = list(range(count))

    def __iter__(self) -> Iterator[int]:
        """The cases, in the order to run them (a copy: :meth:`first` may reorder meanwhile)."""
        return iter(list(self._order))

    def first(self, case: int) -> None:
        """Run ``case`` first for the next candidate."""
        self._order.remove(case)
        self._order.insert(0, case)
