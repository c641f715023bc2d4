"""The paper's three optimizers as it configures them (Table 2; defaults in
``docs/optimizers.md``): CE, GA and SA.

**CE**: Gaussian cross-entropy method with smoothing and dynamic smoothing.

Kroese, Porotsky and Rubinstein (2006), "The Cross-Entropy Method for Continuous Multi-extremal
Optimization". Defaults are the paper's Table 2 (see ``docs/optimizers.md``).

**GA**: real-coded genetic algorithm in the manner of MATLAB's ``ga``.

Rank fitness scaling, stochastic uniform selection, elitism, scattered crossover and an
approximation of MATLAB's (closed-source) adaptive feasible mutation. Defaults are the paper's
Table 2 (see ``docs/optimizers.md``).

**SA**: simulated annealing in the manner of MATLAB's ``simulannealbnd``, as lock-stepped chains.

Fast annealing trial points, the ``acceptancesa`` rule, exponential cooling and reannealing from
estimated sensitivities. SA is sequential, so several independent chains run side by side and
each ``ask()`` returns one trial point per running chain. Defaults are the paper's Table 2 and
MATLAB's (see ``docs/optimizers.md``).
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time

import numpy as np
from scipy.special import expit, ndtr, ndtri

from twin_cosim.optimize.algorithms.base import (
    Optimizer,
    Settings,
    best_decrease,
    ceil_count,
    matlab_round,
    real,
    whole,
)


@dataclasses.dataclass(frozen=True)
class CrossEntropySettings(Settings):
    """Settings of :class:`CrossEntropy` (defaults: the paper's Table 2).

    Attributes
    ----------
    population_size
        Samples per generation, ``N`` (Table 2: 20).
    max_generations
        Generation limit, ``T_max`` (Table 2: 100).
    alpha
        Smoothing factor of the mean (Table 2: 0.6).
    beta
        Dynamic smoothing factor of the standard deviation (Table 2: 0.4).
    q
        Exponent of dynamic smoothing (Table 2: 0.1).
    epsilon
        Stop once the largest standard deviation is below this (Table 2: 1e-10).
    elite_fraction
        Fraction ``rho`` of samples forming the elite, ``ceil(rho N)`` (Table 2: 0.01, so one).
    stall_generations
        Stop after this many generations without improvement of the best, ``d`` (Table 2's
        "maximum valuation number" 10).
    sigma0
        Initial standard deviation in normalised units (not in the paper).
    budget
        Maximum evaluations; ``None`` means ``population_size * max_generations``.
    """

    population_size: int = whole(20, 1)
    max_generations: int = whole(100, 1)
    alpha: float = real(0.6, 0.0, 1.0, low_open=True)
    beta: float = real(0.4, 0.0, 1.0)
    q: float = real(0.1, 0.0, low_open=True)
    epsilon: float = real(1e-10, 0.0)
    elite_fraction: float = real(0.01, 0.0, 1.0, low_open=True)
    stall_generations: int = whole(10, 1)
    sigma0: float = real(0.3, 0.0, low_open=True)
    budget: int | None = whole(None, 1)

    @property
    def max_evaluations(self) -> int:
        """The evaluation budget with ``None`` resolved."""
        if self.budget is None:
            return self.population_size * self.max_generations
        return self.budget


def dynamic_beta(beta: float, q: float, t: int) -> float:
    """Dynamic smoothing factor ``beta_t = beta - beta (1 - 1/t)^q`` for generation ``t >= 1``."""
    return beta - beta * (1.0 - 1.0 / t) ** q


def sample_truncated_normal(
    rng: np.random.Generator, mu: np.ndarray, sigma: np.ndarray, n: int
) -> np.ndarray:
    """Draw ``n`` points from ``N(mu, diag sigma^2)`` truncated to the unit box.

    Each coordinate is drawn by inverting the normal CDF between the box faces, which has the
    distribution of redrawing an out-of-box coordinate until it falls inside, with one uniform
    number per coordinate. Coordinates with ``sigma == 0`` equal ``mu``.

    Parameters
    ----------
    rng
        Random generator.
    mu, sigma
        ``(dim,)`` mean (inside the box) and standard deviation (``>= 0``).
    n
        Number of points.

    Returns
    -------
    numpy.ndarray
        ``(n, dim)`` samples in ``[0, 1]``.
    """
    u = rng.random((n, len(mu)))
    spread = sigma > 0.0
    scale = np.where(spread, sigma, 1.0)
    with np.errstate(over="ignore"):  # a tiny sigma puts a face at -+inf standard deviations
        lo = ndtr(np.where(spread, -mu / scale, 0.0))
        hi = ndtr(np.where(spread, (1.0 - mu) / scale, 0.0))
    # A probability of exactly 0 or 1 gives z = -inf or +inf, which the final clip maps to a face.
    z = ndtri(lo + u * (hi - lo))
    return np.clip(mu + np.where(spread, scale * z, 0.0), 0.0, 1.0)


class CrossEntropy(Optimizer):
    """Cross-entropy method with a diagonal Gaussian, smoothing and dynamic smoothing.

    Each generation draws ``N`` points from ``N(mu, diag sigma^2)`` truncated to the box, takes
    the ``ceil(rho N)`` best as the elite with mean ``mu~`` and standard deviation ``sigma~``
    (``ddof=0``, so a single elite has ``sigma~ = 0``), and updates
    ``mu = alpha mu~ + (1 - alpha) mu`` and ``sigma = beta_t sigma~ + (1 - beta_t) sigma``
    with ``beta_t`` from :func:`dynamic_beta`. The initial mean is ``x0`` or the box centre.

    Stops when ``max(sigma) < epsilon``, after ``max_generations`` generations, after
    ``stall_generations`` generations without improving the best, or when the budget is spent.
    """

    name = "ce"
    settings_type = CrossEntropySettings

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings):
        super().__init__(dim, seed, x0, **settings)
        self.mu = np.full(self.dim, 0.5) if self.x0 is None else self.x0.copy()
        self.sigma = np.full(self.dim, float(self.settings.sigma0))
        self._stall = 0

    def _ask(self, max_points: int) -> np.ndarray:
        n = min(self.settings.population_size, max_points)
        return sample_truncated_normal(self._rng, self.mu, self.sigma, n)

    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        s = self.settings
        t = self.generation
        n_elite = ceil_count(s.elite_fraction, len(fitness))
        elite = x[np.argsort(fitness, kind="stable")[:n_elite]]
        beta_t = dynamic_beta(s.beta, s.q, t)
        self.mu = s.alpha * elite.mean(axis=0) + (1.0 - s.alpha) * self.mu
        self.sigma = beta_t * elite.std(axis=0) + (1.0 - beta_t) * self.sigma
        self._stall = 0 if self._improved else self._stall + 1
        if np.max(self.sigma) < s.epsilon:
            self._stop(f"converged: max sigma {np.max(self.sigma):.3g} < epsilon {s.epsilon:g}")
        elif t >= s.max_generations:
            self._stop(f"generation limit {s.max_generations} reached")
        elif self._stall >= s.stall_generations:
            self._stop(f"no improvement of the best in {s.stall_generations} generations")


#: Smallest mutation step, MATLAB's ``sqrt(eps)``.
MIN_STEP = math.sqrt(np.finfo(np.float64).eps)


@dataclasses.dataclass(frozen=True)
class GeneticSettings(Settings):
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

    population_size: int = whole(100, 2)
    generations: int = whole(20, 1)
    stall_generations: int = whole(10, 1)
    function_tolerance: float = real(1e-6, 0.0)
    elite_fraction: float = real(0.05, 0.0, 1.0, high_open=True)
    crossover_fraction: float = real(0.8, 0.0, 1.0)
    time_limit_s: float | None = real(None, 0.0, low_open=True)
    budget: int | None = whole(None, 1)

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


#: Sensitivities below this fraction of the largest are raised to it before reannealing.
MIN_RELATIVE_SENSITIVITY = 1e-12


@dataclasses.dataclass(frozen=True)
class AnnealingSettings(Settings):
    """Settings of :class:`SimulatedAnnealing`.

    Attributes
    ----------
    initial_temperature
        ``T0`` in normalised units (MATLAB's default 100).
    cooling_factor
        ``T = T0 * cooling_factor^k`` (MATLAB's ``temperatureexp``: 0.95).
    reanneal_interval
        Accepted points between reannealings (MATLAB's default 100).
    stall_iterations
        Window of the stall test, in iterations of a chain (Table 2: 150).
    function_tolerance
        A chain stops when the average decrease of its best per iteration over the stall window
        is below this, in objective units (MATLAB's default 1e-6).
    max_iterations
        Optional trial-point limit per chain; ``None`` (default) for none. Table 2's
        "Generations 300" is not applied by default: see ``docs/optimizers.md``.
    chains
        Independent chains advanced in lock-step (default 4); they split the budget.
    budget
        Maximum evaluations over all chains (Table 2: 18,000 = 3000 x 6 parameters).
    """

    initial_temperature: float = real(100.0, 0.0, low_open=True)
    cooling_factor: float = real(0.95, 0.0, 1.0, low_open=True, high_open=True)
    reanneal_interval: int = whole(100, 1)
    stall_iterations: int = whole(150, 1)
    function_tolerance: float = real(1e-6, 0.0)
    max_iterations: int | None = whole(None, 1)
    chains: int = whole(4, 1)
    budget: int = whole(18_000, 1)


def redraw_out_of_bounds(
    rng: np.random.Generator, trial: np.ndarray, previous: np.ndarray
) -> np.ndarray:
    """MATLAB's bound handling: an out-of-box component is redrawn uniformly between the violated
    bound and its previous (feasible) value.

    Parameters
    ----------
    rng
        Random generator (one uniform number per component is always drawn).
    trial, previous
        Trial point(s) and the current point(s) they were generated from (inside the box), of
        the same shape.

    Returns
    -------
    numpy.ndarray
        The repaired trial point, inside ``[0, 1]``.
    """
    u = rng.random(trial.shape)
    below = previous * u
    above = 1.0 - (1.0 - previous) * u
    return np.where(trial < 0.0, below, np.where(trial > 1.0, above, trial))


def reanneal_parameters(
    k: np.ndarray, cooling_factor: float, sensitivity: np.ndarray
) -> np.ndarray:
    """Annealing parameters after reannealing, MATLAB's ``k_i = ln((T0/T_i) (max_j s_j / s_i))``.

    With ``T_i = T0 * cooling_factor^k_i``, ``ln(T0/T_i) = k_i ln(1/cooling_factor)``, which is
    used instead of the ratio so that a temperature that underflowed to zero stays harmless.

    Parameters
    ----------
    k
        ``(dim,)`` current annealing parameters.
    cooling_factor
        The factor of exponential cooling.
    sensitivity
        ``(dim,)`` non-negative sensitivities with a positive maximum.

    Returns
    -------
    numpy.ndarray
        The new annealing parameters (``>= 0``; smaller means hotter).
    """
    s_max = float(np.max(sensitivity))
    s = np.maximum(sensitivity, s_max * MIN_RELATIVE_SENSITIVITY)
    return k * math.log(1.0 / cooling_factor) + np.log(s_max / s)


def estimate_sensitivity(x: np.ndarray, f: np.ndarray) -> np.ndarray | None:
    """Absolute slopes of a least-squares linear fit ``f ~ a + g . x`` (unit box: ``|g_i|``).

    Non-finite values are left out. Returns ``None`` when fewer than ``dim + 1`` finite points
    remain, when their values are all equal, or when the fit is flat.
    """
    finite = np.isfinite(f)
    x, f = x[finite], f[finite]
    if len(f) <= x.shape[1] or np.ptp(f) == 0.0:
        return None
    design = np.column_stack([np.ones(len(f)), x - x.mean(axis=0)])
    slopes = np.abs(np.linalg.lstsq(design, f, rcond=None)[0][1:])
    return slopes if np.max(slopes) > 0.0 else None


@dataclasses.dataclass(eq=False)
class _Chain:
    """State of one annealing chain."""

    share: int
    x: np.ndarray
    k: np.ndarray
    f: float = math.inf
    used: int = 0
    iterations: int = 0
    best_history: list[float] = dataclasses.field(default_factory=list)
    accepted_x: list[np.ndarray] = dataclasses.field(default_factory=list)
    accepted_f: list[float] = dataclasses.field(default_factory=list)
    stop_reason: str | None = None


class SimulatedAnnealing(Optimizer):
    """Simulated annealing with ``chains`` independent chains advanced in lock-step.

    Each chain evaluates its start point (chain 0 starts at ``x0`` if given; the others, or all
    without ``x0``, at uniform random points), then per iteration: trial
    ``x' = x + T * u`` with ``u`` a uniform random unit direction and ``T`` the per-component
    temperature (MATLAB's ``annealingfast``), out-of-box components redrawn by
    :func:`redraw_out_of_bounds`; acceptance of improvements, otherwise with probability
    ``1 / (1 + exp(delta / max T))`` at the temperature that produced the trial (``delta = 0``
    when both values are ``+inf``); then ``k += 1`` and ``T = T0 cooling_factor^k``. After every
    ``reanneal_interval`` accepted points, ``k`` is reset by :func:`reanneal_parameters` with
    sensitivities from :func:`estimate_sensitivity` over the points accepted since the last
    reannealing (no extra evaluations).

    Chain ``i`` gets ``budget // chains`` evaluations plus one if ``i < budget % chains`` and
    stops when they are spent, after ``max_iterations`` iterations, or when the average decrease
    of its best over ``stall_iterations`` iterations is below ``function_tolerance``. The
    optimizer stops when every chain has stopped.
    """

    name = "sa"
    settings_type = AnnealingSettings

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings):
        super().__init__(dim, seed, x0, **settings)
        n = self.settings.chains
        self.chains = [
            _Chain(
                share=self.budget // n + (i < self.budget % n),
                x=self.x0.copy() if i == 0 and self.x0 is not None else self._rng.random(self.dim),
                k=np.zeros(self.dim),
            )
            for i in range(n)
        ]
        for chain in self.chains:
            if chain.share == 0:
                chain.stop_reason = "no evaluation budget"
        self._active: list[int] = []

    def temperature(self, chain: int) -> np.ndarray:
        """Current per-component temperature of chain number ``chain``."""
        return self._temperature(self.chains[chain])

    def _temperature(self, chain: _Chain) -> np.ndarray:
        s = self.settings
        return s.initial_temperature * s.cooling_factor**chain.k

    def _ask(self, max_points: int) -> np.ndarray:
        self._active = [i for i, c in enumerate(self.chains) if c.stop_reason is None]
        return np.array([self._trial(self.chains[i]) for i in self._active])

    def _trial(self, chain: _Chain) -> np.ndarray:
        if chain.used == 0:
            return chain.x
        u = self._rng.standard_normal(self.dim)
        trial = chain.x + self._temperature(chain) * u / np.linalg.norm(u)
        return redraw_out_of_bounds(self._rng, trial, chain.x)

    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        for i, xi, fi in zip(self._active, x, fitness, strict=True):
            self._advance(self.chains[i], xi, float(fi))
        if all(c.stop_reason is not None for c in self.chains):
            reasons = collections.Counter(c.stop_reason for c in self.chains)
            summary = ", ".join(f"{n} by {reason}" for reason, n in sorted(reasons.items()))
            self._stop(f"all {len(self.chains)} chains stopped: {summary}")

    def _advance(self, chain: _Chain, x: np.ndarray, f: float) -> None:
        if chain.used == 0:
            chain.f = f
        else:
            self._iterate(chain, x, f)
        chain.used += 1
        chain.best_history.append(min(f, chain.best_history[-1]) if chain.best_history else f)
        chain.stop_reason = self._chain_stop_reason(chain)

    def _iterate(self, chain: _Chain, x: np.ndarray, f: float) -> None:
        """Accept or reject a trial at the temperature that produced it, then cool or reanneal."""
        accepted = self._accepts(chain, f)
        chain.iterations += 1
        chain.k += 1.0
        if accepted:
            chain.x, chain.f = x, f
            chain.accepted_x.append(x)
            chain.accepted_f.append(f)
            if len(chain.accepted_f) == self.settings.reanneal_interval:
                self._reanneal(chain)

    def _chain_stop_reason(self, chain: _Chain) -> str | None:
        s = self.settings
        window = s.stall_iterations
        if chain.used >= chain.share:
            return "evaluation budget share"
        if s.max_iterations is not None and chain.iterations >= s.max_iterations:
            return "iteration limit"
        history = chain.best_history
        if (
            len(history) > window
            and best_decrease(history[-1 - window], history[-1]) / window < s.function_tolerance
        ):
            return "stall"
        return None

    def _accepts(self, chain: _Chain, f: float) -> bool:
        if f < chain.f:
            return True
        delta = 0.0 if f == chain.f else f - chain.f
        t_max = max(float(np.max(self._temperature(chain))), np.finfo(np.float64).tiny)
        return bool(self._rng.random() < expit(-delta / t_max))

    def _reanneal(self, chain: _Chain) -> None:
        sensitivity = estimate_sensitivity(np.array(chain.accepted_x), np.array(chain.accepted_f))
        if sensitivity is not None:
            chain.k = reanneal_parameters(chain.k, self.settings.cooling_factor, sensitivity)
        chain.accepted_x.clear()
        chain.accepted_f.clear()
