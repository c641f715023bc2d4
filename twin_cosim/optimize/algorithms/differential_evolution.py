"""Differential evolution baseline: ``scipy.optimize.differential_evolution`` as ask/tell.

SciPy drives the loop and calls the objective, so it runs in a background thread whose objective
hands each population to ``ask()`` through one queue and waits for ``tell()``'s values on another.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import queue
import threading
import weakref
from typing import Any

import numpy as np
from scipy.optimize import differential_evolution

from twin_cosim.optimize.algorithms.base import Optimizer, Settings, check_real, real, whole

#: SciPy renamed ``seed`` to ``rng`` in 1.15; use whichever this SciPy has.
_RNG_KEYWORD = "rng" if "rng" in inspect.signature(differential_evolution).parameters else "seed"

#: The strategies accepted by ``scipy.optimize.differential_evolution``.
STRATEGIES = (
    "best1bin",
    "best1exp",
    "best2bin",
    "best2exp",
    "currenttobest1bin",
    "currenttobest1exp",
    "rand1bin",
    "rand1exp",
    "rand2bin",
    "rand2exp",
    "randtobest1bin",
    "randtobest1exp",
)

#: Sent to the background thread instead of fitness values to abort SciPy.
_ABORT = object()


class _Aborted(Exception):
    """Raised inside the objective to unwind SciPy when the optimizer is closed."""


@dataclasses.dataclass(frozen=True)
class DifferentialEvolutionSettings(Settings):
    """Settings of :class:`DifferentialEvolution` (SciPy's defaults unless noted).

    Attributes
    ----------
    popsize
        Population multiplier: the population is ``max(5, popsize * dim)``.
    mutation
        Differential weight, or a ``(low, high)`` dithering range, in ``[0, 2]``.
    recombination
        Crossover probability in ``[0, 1]``.
    strategy
        One of :data:`STRATEGIES`.
    tol, atol
        SciPy's convergence test ``std(E) <= atol + tol |mean(E)|`` on population energies.
    budget
        Maximum evaluations (default 2,000, the evaluation count of the paper's CE and GA runs).
    """

    popsize: int = whole(15, 1)
    mutation: float | tuple[float, float] = (0.5, 1.0)
    recombination: float = real(0.7, 0.0, 1.0)
    strategy: str = "best1bin"
    tol: float = real(0.01, 0.0)
    atol: float = real(0.0, 0.0)
    budget: int = whole(2000, 1)

    def __post_init__(self) -> None:
        super().__post_init__()  # popsize, recombination, tol, atol, budget
        if isinstance(self.mutation, tuple):
            if len(self.mutation) != 2 or not self.mutation[0] <= self.mutation[1]:
                raise ValueError(
                    f"setting 'mutation' must be a number or a (low, high) pair with "
                    f"low <= high, got {self.mutation!r}"
                )
            for value in self.mutation:
                check_real("mutation", value, 0.0, 2.0)
        else:
            check_real("mutation", self.mutation, 0.0, 2.0)
        if self.strategy not in STRATEGIES:
            raise ValueError(
                f"setting 'strategy' must be one of {', '.join(STRATEGIES)}, got {self.strategy!r}"
            )


def _run_scipy(kwargs: dict[str, Any], requests: queue.Queue, replies: queue.Queue) -> None:
    """Thread body: run SciPy, posting ``("batch", x)``, then ``("done", msg)`` or ``("error",
    exc)`` to ``requests``; read fitness arrays or :data:`_ABORT` from ``replies``.

    It holds no reference to the optimizer, so an abandoned optimizer can be garbage collected
    and its finalizer can abort the thread.
    """

    def objective(xt: np.ndarray) -> np.ndarray:
        requests.put(("batch", np.ascontiguousarray(xt.T)))
        reply = replies.get()
        if reply is _ABORT:
            raise _Aborted
        return reply

    try:
        result = differential_evolution(objective, **kwargs)
    except _Aborted:
        return
    except Exception as exc:  # handed to the caller's thread, which re-raises it
        requests.put(("error", exc))
        return
    requests.put(("done", str(result.message)))


def _shutdown(thread: threading.Thread, replies: queue.Queue) -> None:
    """Abort the SciPy thread if it is still running and wait for it to exit."""
    if thread.is_alive():
        replies.put(_ABORT)
        thread.join()


class DifferentialEvolution(Optimizer):
    """SciPy's differential evolution behind ask/tell.

    SciPy runs with ``polish=False``, ``vectorized=True`` and ``updating="deferred"``, so each
    call of the objective is one whole population (the initial one, then one trial population per
    generation), seeded with ``numpy.random.default_rng(seed)``; ``x0`` replaces the first
    member of the initial population. ``maxiter`` is set so that SciPy's own generation limit
    never ends the run before the budget; the batch that reaches the budget is truncated and
    SciPy is aborted. SciPy's convergence test sets ``stop_reason``.

    The thread starts at the first ``ask()`` and ends when the run stops, on :meth:`close`, or
    when the optimizer is garbage collected or the interpreter exits.
    """

    name = "de"
    settings_type = DifferentialEvolutionSettings

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings):
        super().__init__(dim, seed, x0, **settings)
        s = self.settings
        self.population_size = max(5, s.popsize * self.dim)
        self._scipy_kwargs: dict[str, Any] = {
            "bounds": [(0.0, 1.0)] * self.dim,
            "strategy": s.strategy,
            "maxiter": max(math.ceil(self.budget / self.population_size) - 1, 0),
            "popsize": s.popsize,
            "tol": s.tol,
            "atol": s.atol,
            "mutation": s.mutation,
            "recombination": s.recombination,
            _RNG_KEYWORD: self._rng,
            "polish": False,
            "updating": "deferred",
            "vectorized": True,
            "x0": self.x0,
        }
        self._requests: queue.Queue = queue.Queue()
        self._replies: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None
        self._finalizer: weakref.finalize | None = None
        self._batch = np.empty((0, self.dim))

    def _ask(self, max_points: int) -> np.ndarray:
        if self._thread is None:
            self._thread = threading.Thread(
                target=_run_scipy,
                args=(self._scipy_kwargs, self._requests, self._replies),
                name=f"scipy-de-seed{self.seed}",
                daemon=True,
            )
            self._finalizer = weakref.finalize(self, _shutdown, self._thread, self._replies)
            self._thread.start()
            self._receive()
        return np.clip(self._batch[:max_points], 0.0, 1.0)

    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        if self.remaining_budget <= 0:
            return
        self._replies.put(fitness)
        self._receive()

    def _receive(self) -> None:
        """Wait for SciPy's next batch request or its end."""
        kind, payload = self._requests.get()
        if kind == "batch":
            self._batch = payload
        elif kind == "done":
            self._stop(f"scipy: {payload}")
            self.close()
        else:
            self._stop(f"scipy failed: {payload!r}")
            self.close()
            raise RuntimeError("scipy differential_evolution failed") from payload

    def close(self) -> None:
        """End the run, abort SciPy if it is still running and join its thread; idempotent."""
        super().close()
        if self._finalizer is not None:
            self._finalizer()

    @property
    def thread_alive(self) -> bool:
        """Whether the background SciPy thread is running."""
        return self._thread is not None and self._thread.is_alive()
