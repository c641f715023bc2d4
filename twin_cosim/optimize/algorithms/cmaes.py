"""CMA-ES baseline: an ask/tell adapter over pycma (``cma.CMAEvolutionStrategy``)."""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from typing import Any

import cma
import numpy as np

from twin_cosim.optimize.algorithms.base import Optimizer, Settings, real, whole


@dataclasses.dataclass(frozen=True)
class CMAESSettings(Settings):
    """Settings of :class:`CMAES`.

    Attributes
    ----------
    sigma0
        Initial step size in normalised units.
    popsize
        Population size; ``None`` for pycma's default ``4 + floor(3 ln dim)``.
    max_flat_generations
        pycma's ``tolflatfitness``: generations with all-equal fitness (for instance every
        candidate failed with ``+inf``) tolerated before stopping. pycma's default of 1 would end
        a run whose first generation lies entirely in a failing region; default here 10.
    budget
        Maximum evaluations (default 2,000, the evaluation count of the paper's CE and GA runs).
    inject_start
        Evaluate the start point ``x0`` with the first generation (pycma's ``inject``): a
        refinement of a known good set ranks it with the samples, so its best is never worse
        than the start. Default False: the start is only the mean of the first samples.
    """

    sigma0: float = real(0.3, 0.0, low_open=True)
    popsize: int | None = whole(None, 2)
    max_flat_generations: int = whole(10, 1)
    budget: int = whole(2000, 1)
    inject_start: bool = False


def pycma_seed(seed: int) -> int:
    """Map a non-negative seed to pycma's: pycma reads 0 as "seed from the clock"."""
    return seed % (2**32 - 1) + 1


class CMAES(Optimizer):
    """CMA-ES through pycma with bounds ``[0, 1]`` handled by pycma (``BoundTransform``).

    pycma draws from NumPy's legacy global generator, which it seeds from the ``seed`` option at
    construction. To make each instance a pure function of its seed regardless of other users of
    that generator, the adapter keeps its own copy of the global state and swaps it in around
    every pycma call (not safe against other threads using ``numpy.random`` at the same moment).

    Told ``+inf`` values are passed to pycma unchanged (it ranks them last; a generation of only
    ``+inf`` is flat fitness, on which pycma widens ``sigma``). A batch truncated by
    the budget is not told to pycma, since the run ends with it. pycma's own termination
    criteria (``tolfun``, ``tolx``, ...) set ``stop_reason``.
    """

    name = "cmaes"
    settings_type = CMAESSettings

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings):
        super().__init__(dim, seed, x0, **settings)
        options: dict[str, Any] = {
            "bounds": [0.0, 1.0],
            "seed": pycma_seed(self.seed),
            "tolflatfitness": self.settings.max_flat_generations,
            "verbose": -9,
            "verb_disp": 0,
            "verb_log": 0,
        }
        if self.settings.popsize is not None:
            options["popsize"] = self.settings.popsize
        start = np.full(self.dim, 0.5) if self.x0 is None else self.x0
        self._numpy_state = np.random.get_state()  # noqa: NPY002 (pycma uses the global one)
        with self._own_global_rng():
            self.es = cma.CMAEvolutionStrategy(start, self.settings.sigma0, options)
            if self.settings.inject_start and self.x0 is not None:  # pycma injects genotypes
                self.es.inject([self.es.boundary_handler.inverse(start)], force=True)
        self._asked: list[np.ndarray] = []

    @contextlib.contextmanager
    def _own_global_rng(self) -> Iterator[None]:
        """Swap this instance's state of ``numpy.random``'s global generator in and back out."""
        outside = np.random.get_state()  # noqa: NPY002
        np.random.set_state(self._numpy_state)  # noqa: NPY002
        try:
            yield
        finally:
            self._numpy_state = np.random.get_state()  # noqa: NPY002
            np.random.set_state(outside)  # noqa: NPY002

    def _ask(self, max_points: int) -> np.ndarray:
        with self._own_global_rng():
            self._asked = self.es.ask()
        return np.clip(np.array(self._asked[:max_points]), 0.0, 1.0)

    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        if len(fitness) < len(self._asked):
            return
        with self._own_global_rng():
            self.es.tell(self._asked, fitness.tolist())
            stop = self.es.stop()
        if stop:
            self._stop("pycma: " + ", ".join(f"{key}={value}" for key, value in stop.items()))
