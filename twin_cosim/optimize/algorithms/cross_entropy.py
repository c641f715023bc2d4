"""Gaussian cross-entropy method with smoothing and dynamic smoothing.

Kroese, Porotsky and Rubinstein (2006), "The Cross-Entropy Method for Continuous Multi-extremal
Optimization". Defaults are the paper's Table 2 (see ``docs/optimizers.md``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.special import ndtr, ndtri

from twin_cosim.optimize.algorithms.base import Optimizer, ceil_count, check_int, check_real


@dataclasses.dataclass(frozen=True)
class CrossEntropySettings:
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

    population_size: int = 20
    max_generations: int = 100
    alpha: float = 0.6
    beta: float = 0.4
    q: float = 0.1
    epsilon: float = 1e-10
    elite_fraction: float = 0.01
    stall_generations: int = 10
    sigma0: float = 0.3
    budget: int | None = None

    def __post_init__(self) -> None:
        check_int("population_size", self.population_size, 1)
        check_int("max_generations", self.max_generations, 1)
        check_real("alpha", self.alpha, 0.0, 1.0, low_open=True)
        check_real("beta", self.beta, 0.0, 1.0)
        check_real("q", self.q, 0.0, low_open=True)
        check_real("epsilon", self.epsilon, 0.0)
        check_real("elite_fraction", self.elite_fraction, 0.0, 1.0, low_open=True)
        check_int("stall_generations", self.stall_generations, 1)
        check_real("sigma0", self.sigma0, 0.0, low_open=True)
        if self.budget is not None:
            check_int("budget", self.budget, 1)

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
