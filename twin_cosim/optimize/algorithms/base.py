"""Common ask/tell interface and settings helpers for the batch optimizers.

Every optimizer works in the normalised unit box ``[0, 1]^dim``; the caller maps points to
physical bounds. An optimizer is a pure function of ``(seed, settings, told fitness values)``:
replaying the same told values from the same seed reproduces the same asks, which is what lets a
campaign resume from an evaluation cache.
"""

from __future__ import annotations

import abc
import dataclasses
import math
import numbers
from typing import Any, ClassVar

import numpy as np


def build_settings(settings_type: type, overrides: dict[str, Any]) -> Any:
    """Instantiate a settings dataclass from keyword overrides.

    Parameters
    ----------
    settings_type
        A dataclass whose fields all have defaults.
    overrides
        Setting names and values replacing the defaults.

    Returns
    -------
    object
        The validated settings instance (validation runs in its ``__post_init__``).

    Raises
    ------
    ValueError
        If a name is not a field of ``settings_type``; the message lists the valid names.
    """
    valid = sorted(field.name for field in dataclasses.fields(settings_type))
    unknown = sorted(set(overrides) - set(valid))
    if unknown:
        raise ValueError(
            f"unknown setting(s) {', '.join(map(repr, unknown))} for {settings_type.__name__}; "
            f"valid settings: {', '.join(valid)}"
        )
    return settings_type(**overrides)


def check_int(name: str, value: Any, minimum: int) -> None:
    """Raise ``ValueError`` unless ``value`` is an integer (not a bool) ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"setting {name!r} must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"setting {name!r} must be >= {minimum}, got {value!r}")


def check_real(
    name: str,
    value: Any,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> None:
    """Raise ``ValueError`` unless ``value`` is a real number inside the given interval.

    Parameters
    ----------
    name, value
        Setting name (for the message) and value.
    low, high
        Interval ends.
    low_open, high_open
        Whether the corresponding end is excluded.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or math.isnan(value):
        raise ValueError(f"setting {name!r} must be a real number, got {value!r}")
    too_low = value <= low if low_open else value < low
    too_high = value >= high if high_open else value > high
    if too_low or too_high:
        interval = f"{'(' if low_open else '['}{low}, {high}{')' if high_open else ']'}"
        raise ValueError(f"setting {name!r} must lie in {interval}, got {value!r}")


def matlab_round(value: float) -> int:
    """Round half away from zero for non-negative values (MATLAB's ``round``)."""
    return math.floor(value + 0.5)


def ceil_count(fraction: float, total: int) -> int:
    """``ceil(fraction * total)`` robust to floating error (``0.05 * 100`` gives 5, not 6)."""
    return math.ceil(round(fraction * total, 9))


def best_decrease(old: float, new: float) -> float:
    """Decrease of a best-so-far value from ``old`` to ``new``; ``inf`` while ``old`` is ``inf``.

    A window that starts before any finite value was seen never counts as stalled, and the
    ``inf - inf`` NaN is avoided.
    """
    return math.inf if math.isinf(old) else old - new


def whole(default: int | None, minimum: int) -> Any:
    """A setting that is a whole number ``>= minimum`` (:func:`check_int`); a default of None
    lets None stand for "not set"."""
    return dataclasses.field(default=default, metadata={"check": (check_int, (minimum,), {})})


def real(
    default: float | None,
    low: float = -math.inf,
    high: float = math.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> Any:
    """A setting that is a real number in an interval (:func:`check_real`); a default of None
    lets None stand for "not set"."""
    keywords = {"low_open": low_open, "high_open": high_open}
    return dataclasses.field(
        default=default, metadata={"check": (check_real, (low, high), keywords)}
    )


@dataclasses.dataclass(frozen=True)
class Settings:
    """An optimizer's settings: a frozen dataclass whose fields declared by :func:`whole` and
    :func:`real` are checked when it is made (a subclass checks the rest in its own
    ``__post_init__``, after this one's)."""

    def __post_init__(self) -> None:
        for setting in dataclasses.fields(self):
            value = getattr(self, setting.name)
            if "check" not in setting.metadata or (value is None and setting.default is None):
                continue
            check, limits, keywords = setting.metadata["check"]
            check(setting.name, value, *limits, **keywords)


class Optimizer(abc.ABC):
    """Batch ask/tell optimizer in the normalised unit box.

    Parameters
    ----------
    dim
        Number of parameters.
    seed
        Non-negative integer seeding every random choice of the algorithm.
    x0
        Optional starting point in ``[0, 1]^dim``.
    **settings
        Overrides of the fields of the algorithm's settings dataclass (``settings_type``).

    Attributes
    ----------
    name : str
        Registry name of the algorithm.
    settings
        The validated settings dataclass instance.
    budget : int
        Maximum number of evaluations.
    evaluations : int
        Number of fitness values told so far.
    generation : int
        Number of completed ``tell()`` calls.

    Notes
    -----
    Calls must alternate ``ask()``, ``tell()``. Once ``stop_reason`` is set, ``ask()`` returns an
    empty ``(0, dim)`` array. ``close()`` (also called on leaving a ``with`` block and when the
    run stops) ends the run and releases resources. Subclasses implement ``_ask`` and ``_tell``;
    this class does the budget accounting, best-point tracking and input validation.
    """

    name: ClassVar[str]
    settings_type: ClassVar[type]

    def __init__(self, dim: int, seed: int, x0: np.ndarray | None = None, **settings: Any):
        if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
            raise ValueError(f"dim must be a positive integer, got {dim!r}")
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        self.dim = int(dim)
        self.seed = int(seed)
        self.x0 = None if x0 is None else self._validated_x0(x0)
        self.settings = build_settings(self.settings_type, settings)
        # a budget given, else the method's own (CE and GA: from the population and generations)
        given = self.settings.budget
        self.budget: int = self.settings.max_evaluations if given is None else given
        self.evaluations = 0
        self.generation = 0
        self._rng = np.random.default_rng(self.seed)
        self._pending: np.ndarray | None = None
        self._stop_reason: str | None = None
        self._best_x: np.ndarray | None = None
        self._best_f = math.inf
        self._improved = False

    def _validated_x0(self, x0: np.ndarray) -> np.ndarray:
        x = np.array(x0, dtype=np.float64)
        if x.shape != (self.dim,):
            raise ValueError(f"x0 must have shape ({self.dim},), got {x.shape}")
        if not np.all((x >= 0.0) & (x <= 1.0)):
            raise ValueError("x0 must lie in the normalised box [0, 1]^dim")
        return x

    @property
    def stop_reason(self) -> str | None:
        """``None`` while running, else a short human-readable reason."""
        return self._stop_reason

    @property
    def best(self) -> tuple[np.ndarray, float]:
        """Best point told so far (normalised) and its fitness; earliest wins ties.

        Raises
        ------
        RuntimeError
            Before the first ``tell()``.
        """
        if self._best_x is None:
            raise RuntimeError("no point has been evaluated yet")
        return self._best_x.copy(), self._best_f

    @property
    def remaining_budget(self) -> int:
        """Evaluations left before the budget is exhausted."""
        return self.budget - self.evaluations

    def ask(self) -> np.ndarray:
        """Return the next batch of points to evaluate.

        Returns
        -------
        numpy.ndarray
            ``(n, dim)`` float64 array in ``[0, 1]``, ``1 <= n <= remaining_budget``; ``n = 0``
            once stopped.

        Raises
        ------
        RuntimeError
            If the previous batch has not been told yet.
        """
        if self._pending is not None:
            raise RuntimeError("ask() called again before tell() for the previous batch")
        if self._stop_reason is not None:
            return np.empty((0, self.dim))
        self._pending = np.array(self._ask(self.remaining_budget), dtype=np.float64)
        return self._pending.copy()

    def tell(self, fitness: np.ndarray) -> None:
        """Report the fitness of the last asked batch (lower is better).

        Parameters
        ----------
        fitness
            ``(n,)`` values for the ``n`` points of the last ``ask()``; ``+inf`` marks a failed
            candidate.

        Raises
        ------
        RuntimeError
            If there is no asked batch waiting for its values (none asked, or closed since).
        ValueError
            On a shape mismatch or a NaN or ``-inf`` value.
        """
        if self._pending is None:
            raise RuntimeError("tell() called without a pending ask() (or after close())")
        f = np.array(fitness, dtype=np.float64)
        if f.shape != (len(self._pending),):
            raise ValueError(f"expected fitness of shape ({len(self._pending)},), got {f.shape}")
        if np.any(np.isnan(f) | (f == -np.inf)):
            raise ValueError("fitness must be finite or +inf (no NaN, no -inf)")
        x, self._pending = self._pending, None
        self.evaluations += len(f)
        self.generation += 1
        i = int(np.argmin(f))
        self._improved = self._best_x is None or f[i] < self._best_f
        if self._improved:
            self._best_x, self._best_f = x[i].copy(), float(f[i])
        self._tell(x, f)
        if self.remaining_budget <= 0:
            self._stop(f"evaluation budget of {self.budget} exhausted")
        if self._stop_reason is not None:
            self.close()

    def close(self) -> None:
        """End the run and release resources (background threads); idempotent.

        A run closed before its end gets the stop reason ``"closed"``; an outstanding batch is
        dropped, later ``ask()`` calls return empty batches. Subclasses holding resources extend
        this.
        """
        self._stop("closed")
        self._pending = None

    def __enter__(self) -> Optimizer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _stop(self, reason: str) -> None:
        """Record the first stop reason; later ones are ignored."""
        if self._stop_reason is None:
            self._stop_reason = reason

    @abc.abstractmethod
    def _ask(self, max_points: int) -> np.ndarray:
        """Return between 1 and ``max_points`` points of the next batch, inside the box."""

    @abc.abstractmethod
    def _tell(self, x: np.ndarray, fitness: np.ndarray) -> None:
        """Update the algorithm with the batch ``x`` and its validated ``fitness``."""
