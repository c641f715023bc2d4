"""Simulated annealing in the manner of MATLAB's ``simulannealbnd``, as lock-stepped chains.

Fast annealing trial points, the ``acceptancesa`` rule, exponential cooling and reannealing from
estimated sensitivities. SA is sequential, so several independent chains run side by side and
each ``ask()`` returns one trial point per running chain. Defaults are the paper's Table 2 and
MATLAB's (see ``docs/optimizers.md``).
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np
from scipy.special import expit

from twin_cosim.optimize.algorithms.base import Optimizer, best_decrease, check_int, check_real

#: Sensitivities below this fraction of the largest are raised to it before reannealing.
MIN_RELATIVE_SENSITIVITY = 1e-12


@dataclasses.dataclass(frozen=True)
class AnnealingSettings:
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

    initial_temperature: float = 100.0
    cooling_factor: float = 0.95
    reanneal_interval: int = 100
    stall_iterations: int = 150
    function_tolerance: float = 1e-6
    max_iterations: int | None = None
    chains: int = 4
    budget: int = 18_000

    def __post_init__(self) -> None:
        check_real("initial_temperature", self.initial_temperature, 0.0, low_open=True)
        check_real("cooling_factor", self.cooling_factor, 0.0, 1.0, low_open=True, high_open=True)
        check_int("reanneal_interval", self.reanneal_interval, 1)
        check_int("stall_iterations", self.stall_iterations, 1)
        check_real("function_tolerance", self.function_tolerance, 0.0)
        if self.max_iterations is not None:
            check_int("max_iterations", self.max_iterations, 1)
        check_int("chains", self.chains, 1)
        check_int("budget", self.budget, 1)


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
