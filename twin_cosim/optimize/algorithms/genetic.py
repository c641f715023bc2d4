"""Real-coded genetic algorithm in the manner of MATLAB's ``ga``.

Rank fitness scaling, stochastic uniform selection, elitism, scattered crossover and an
approximation of MATLAB's (closed-source) adaptive feasible mutation. Defaults are the paper's
Table 2 (see ``docs/optimizers.md``).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from twin_cosim.optimize.algorithms.base import (
    Optimizer,
    best_decrease,
    ceil_count,
    check_int,
    check_real,
    matlab_round,
)

#: Smallest mutation step, MATLAB's ``sqrt(eps)``.
MIN_STEP = math.sqrt(np.finfo(np.float64).eps)


@dataclasses.dataclass(frozen=True)
class GeneticSettings:
    """Settings of :class:`GeneticAlgorithm` (defaults: the paper's Table 2 and MATLAB's ``ga``).

    Attributes
    ----------
    population_size
        Individuals per generation (Table 2: 100).
    generations
        Generations after the initial population (Table 2: 20).
    stall_generations
        Window of the stall test (Table 2: 10).
    function_tolerance
        Stop when the relative decrease of the best over the stall window is below this
        (MATLAB's default 1e-6).
    elite_fraction
        Elite count is ``ceil(elite_fraction * population_size)`` (MATLAB: 0.05).
    crossover_fraction
        Fraction of the non-elite children made by crossover, rounded (MATLAB: 0.8).
    time_limit_s
        Wall-clock limit in seconds, ``None`` to disable (default). Table 2's 50 s is not applied
        by default: see ``docs/optimizers.md``. Setting it makes runs irreproducible.
    budget
        Maximum evaluations; ``None`` means the population plus ``generations`` times the
        non-elite children (2,000 with the defaults).
    """

    population_size: int = 100
    generations: int = 20
    stall_generations: int = 10
    function_tolerance: float = 1e-6
    elite_fraction: float = 0.05
    crossover_fraction: float = 0.8
    time_limit_s: float | None = None
    budget: int | None = None

    def __post_init__(self) -> None:
        check_int("population_size", self.population_size, 2)
        check_int("generations", self.generations, 1)
        check_int("stall_generations", self.stall_generations, 1)
        check_real("function_tolerance", self.function_tolerance, 0.0)
        check_real("elite_fraction", self.elite_fraction, 0.0, 1.0, high_open=True)
        check_real("crossover_fraction", self.crossover_fraction, 0.0, 1.0)
        if self.time_limit_s is not None:
            check_real("time_limit_s", self.time_limit_s, 0.0, low_open=True)
        if self.budget is not None:
            check_int("budget", self.budget, 1)

    @property
    def child_counts(self) -> tuple[int, int, int]:
        """Elite, crossover and mutation children per generation (5, 76, 19 for 100)."""
        n_elite = ceil_count(self.elite_fraction, self.population_size)
        n_crossover = matlab_round(self.crossover_fraction * (self.population_size - n_elite))
        return n_elite, n_crossover, self.population_size - n_elite - n_crossover

    @property
    def max_evaluations(self) -> int:
        """The evaluation budget with ``None`` resolved."""
        if self.budget is None:
            n_elite = self.child_counts[0]
            return self.population_size + self.generations * (self.population_size - n_elite)
        return self.budget


def rank_scaling(fitness: np.ndarray, total: float) -> np.ndarray:
    """MATLAB's ``fitscalingrank``: expectation proportional to ``1/sqrt(rank)``, summing to total.

    Ranks come from a stable ascending sort, so ties (including ``+inf``) are ranked by index.
    """
    ranks = np.empty(len(fitness))
    ranks[np.argsort(fitness, kind="stable")] = np.arange(1, len(fitness) + 1)
    expectation = 1.0 / np.sqrt(ranks)
    return total * expectation / expectation.sum()


def stochastic_uniform(
    rng: np.random.Generator, expectation: np.ndarray, n_parents: int
) -> np.ndarray:
    """MATLAB's ``selectionstochunif``: equal steps along a line of expectation sections.

    Returns the indices of ``n_parents`` parents; the first position is uniform in ``[0, step)``.
    """
    wheel = np.cumsum(expectation) / n_parents
    step = 1.0 / n_parents
    positions = rng.random() * step + step * np.arange(n_parents)
    return np.minimum(np.searchsorted(wheel, positions, side="right"), len(wheel) - 1)


def scattered_crossover(
    rng: np.random.Generator, first: np.ndarray, second: np.ndarray
) -> np.ndarray:
    """MATLAB's ``crossoverscattered``: each gene from ``first`` or ``second`` by a coin flip."""
    return np.where(rng.random(first.shape) < 0.5, first, second)


def feasible_direction_mutation(
    rng: np.random.Generator, parents: np.ndarray, step: float
) -> np.ndarray:
    """Move each parent by ``step`` along a random unit direction, kept inside the unit box.

    The sign of the direction that leaves more room is used; if ``step`` still leaves the box,
    it is halved until the child is feasible (children stay put only if both signs are blocked,
    e.g. at a corner).
    """
    u = rng.standard_normal(parents.shape)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    room = _room_along(parents, u)
    flip = _room_along(parents, -u) > room
    u[flip] = -u[flip]
    room = np.maximum(room, _room_along(parents, u))
    with np.errstate(divide="ignore"):
        halvings = np.ceil(np.log2(np.where(room > 0.0, step / room, 1.0)))
    length = np.where(room > 0.0, step / 2.0 ** np.maximum(halvings, 0.0), 0.0)
    return np.clip(parents + length[:, None] * u, 0.0, 1.0)


def _room_along(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Largest ``t >= 0`` with ``x + t u`` inside the unit box, row by row."""
    with np.errstate(divide="ignore", invalid="ignore"):
        limit = np.where(u > 0.0, (1.0 - x) / u, np.where(u < 0.0, -x / u, np.inf))
    return limit.min(axis=1)


def relative_decrease(old: float, new: float) -> float:
    """Decrease of the best from ``old`` to ``new`` relative to ``|old|`` (absolute if 0)."""
    decrease = best_decrease(old, new)
    return decrease / abs(old) if old != 0.0 and math.isfinite(decrease) else decrease


class GeneticAlgorithm(Optimizer):
    """Real-coded GA in the manner of MATLAB's ``ga`` with bounds.

    The first ask is the initial population, uniform in the box (``x0`` replaces its first
    member). Each later generation keeps the ``ceil(0.05 Pop)`` best as elite (not re-evaluated)
    and asks for the other children: ``round(0.8 (Pop - elite))`` by scattered crossover of
    stochastic-uniform-selected parents after rank scaling, the rest by
    :func:`feasible_direction_mutation`. The mutation step is 1 for the first two generations;
    afterwards it is multiplied by 4 (at most 1) when the population spread (mean per-coordinate
    standard deviation) grew in the last generation, else divided by 4 (at least ``sqrt(eps)``).

    Stops after ``generations`` generations, when the relative decrease of the best over the last
    ``stall_generations`` generations is below ``function_tolerance``, when the optional wall-clock
    limit passes, or when the budget is spent.
    """

    name = "ga"
    settings_type = GeneticSettings

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings):
        super().__init__(dim, seed, x0, **settings)
        self.population = np.empty((0, self.dim))
        self.scores = np.empty(0)
        self.step = 1.0
        self._spread = math.inf
        self._elite = np.empty((0, self.dim))
        self._elite_scores = np.empty(0)
        self._best_history: list[float] = []
        self._started = time.monotonic()

    @property
    def ga_generation(self) -> int:
        """Generations completed after the initial population (``generation - 1``)."""
        return max(self.generation - 1, 0)

    def _ask(self, max_points: int) -> np.ndarray:
        if self.generation == 0:
            children = self._rng.random((self.settings.population_size, self.dim))
            if self.x0 is not None:
                children[0] = self.x0
        else:
            children = self._breed()
        return children[:max_points]

    def _breed(self) -> np.ndarray:
        n_elite, n_crossover, n_mutation = self.settings.child_counts
        order = np.argsort(self.scores, kind="stable")
        self._elite = self.population[order[:n_elite]]
        self._elite_scores = self.scores[order[:n_elite]]
        n_parents = 2 * n_crossover + n_mutation
        expectation = rank_scaling(self.scores, n_parents)
        parents = self._rng.permutation(stochastic_uniform(self._rng, expectation, n_parents))
        pairs = self.population[parents[: 2 * n_crossover]].reshape(n_crossover, 2, self.dim)
        crossover = scattered_crossover(self._rng, pairs[:, 0], pairs[:, 1])
        mutants = self.population[parents[2 * n_crossover :]]
        mutation = feasible_direction_mutation(self._rng, mutants, self.step)
        return np.concatenate([crossover, mutation])

    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        s = self.settings
        self.population = np.concatenate([self._elite, x])
        self.scores = np.concatenate([self._elite_scores, fitness])
        self._best_history.append(self._best_f)
        spread = float(np.mean(np.std(self.population, axis=0)))
        if self.ga_generation >= 2:
            self.step = min(1.0, 4.0 * self.step) if spread > self._spread else self.step / 4.0
            self.step = max(self.step, MIN_STEP)
        self._spread = spread
        window = s.stall_generations
        if self.ga_generation >= s.generations:
            self._stop(f"generation limit {s.generations} reached")
        elif (
            len(self._best_history) > window
            and relative_decrease(self._best_history[-1 - window], self._best_f)
            < s.function_tolerance
        ):
            self._stop(
                f"stalled: relative change of the best over {window} generations "
                f"< {s.function_tolerance:g}"
            )
        elif s.time_limit_s is not None and time.monotonic() - self._started > s.time_limit_s:
            self._stop(f"time limit {s.time_limit_s:g} s exceeded")
