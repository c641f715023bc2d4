"""Sequential change detection on per-window statistics: CUSUM tests whose false-alarm rate is
chosen from the stationary machine's window-to-window scatter.

Each statistic y_w (a tracked effect's value, the gap the effects leave) is standardised by the
mean and the spread of the baseline windows, z_w = (y_w - mean) / spread, and fed to Page's
CUSUM: S_w = max(0, S_{w-1} + z_w - k) upwards (and the same on -z_w downwards for a two-sided
test); the test alarms when S_w exceeds h. The change began after the last window at which S was
0.

The spread is the baseline windows' sample standard deviation raised to its upper confidence
bound (:data:`SPREAD_CONFIDENCE`: a spread measured on a few windows is too small as often as
too large, and a spread too small makes every window an alarm): with n baseline windows,
s sqrt((n - 1) / chi2_{n-1}(1 - confidence)). The allowance k is half a spread (the test most
sensitive to a shift of one spread), and h is set for an average run length without change
(ARL0, in windows) by Siegmund's approximation for normal increments,

    ARL0 = (exp(2 k b) - 2 k b - 1) / (2 k^2),  b = h + 1.166,

shared by the tests run side by side: each of m one-sided tests gets m times the design ARL0,
so that the first false alarm of any of them comes after the design ARL0 on average.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

ALLOWANCE = 0.5  # k, in spreads
SPREAD_CONFIDENCE = 0.9  # the spread used is the upper bound of this one-sided confidence
SIEGMUND_OFFSET = 1.166


def siegmund_arl(h: float, k: float = ALLOWANCE) -> float:
    """Average run length (windows) of a one-sided CUSUM with threshold ``h`` and allowance
    ``k`` (both in spreads) on standard normal increments, by Siegmund's approximation."""
    b = 2.0 * k * (h + SIEGMUND_OFFSET)
    return (math.exp(b) - b - 1.0) / (2.0 * k * k)


def threshold_for(arl0: float, k: float = ALLOWANCE) -> float:
    """The threshold h (spreads) whose one-sided ARL0 (windows) is ``arl0``."""
    if arl0 <= 1.0:
        raise ValueError(f"an average run length must exceed 1 window, got {arl0}")
    low, high = 0.0, 100.0
    for _ in range(100):  # bisection: the ARL grows with h
        middle = 0.5 * (low + high)
        low, high = (middle, high) if siegmund_arl(middle, k) < arl0 else (low, middle)
    return high


def chi2_lower_quantile(dof: int, probability: float) -> float:
    """The ``probability`` quantile of a chi-square of ``dof`` degrees of freedom."""
    from scipy.stats import chi2

    return float(chi2.ppf(probability, dof))


def baseline_spread(values: np.ndarray, floor: float = 0.0) -> float:
    """The spread of a statistic from its baseline values: the sample standard deviation at its
    upper confidence bound (:data:`SPREAD_CONFIDENCE`), at least ``floor``.

    Raises
    ------
    ValueError
        With fewer than 3 values.
    """
    values = np.asarray(values, dtype=float)
    n = len(values)
    if n < 3:
        raise ValueError(f"the spread of a statistic needs at least 3 baseline windows, got {n}")
    spread = float(np.std(values, ddof=1))
    bound = math.sqrt((n - 1) / chi2_lower_quantile(n - 1, 1.0 - SPREAD_CONFIDENCE))
    return max(spread * bound, floor)


@dataclass
class Cusum:
    """Page's CUSUM on one statistic, one- or two-sided.

    Attributes
    ----------
    name : str
        The statistic.
    mean, spread : float
        Baseline mean and spread (the statistic's unit).
    threshold : float
        h, in spreads.
    two_sided : bool
        Also watch a fall (else a rise only).
    upper, lower : float
        The running sums (spreads).
    upper_start, lower_start : int
        The window after the last one at which each sum was 0: where a change began.
    crossed : int or None
        The window at which the test alarmed (None: not yet); it alarms once.
    """

    name: str
    mean: float
    spread: float
    threshold: float
    two_sided: bool = True
    upper: float = 0.0
    lower: float = 0.0
    upper_start: int = 0
    lower_start: int = 0
    crossed: int | None = None
    history: list[tuple[int, float]] = field(default_factory=list)

    def update(self, window: int, value: float) -> bool:
        """Feed the statistic of ``window``; True when the test alarms at this window."""
        z = (value - self.mean) / self.spread
        self.history.append((window, value))
        if self.upper == 0.0:
            self.upper_start = window
        if self.lower == 0.0:
            self.lower_start = window
        self.upper = max(0.0, self.upper + z - ALLOWANCE)
        if self.two_sided:
            self.lower = max(0.0, self.lower - z - ALLOWANCE)
        if self.crossed is None and self.score > 1.0:
            self.crossed = window
            return True
        return False

    @property
    def score(self) -> float:
        """The larger running sum over the threshold (1: at the threshold)."""
        return max(self.upper, self.lower) / self.threshold

    @property
    def direction(self) -> int:
        """+1 when the rise leads, -1 when the fall does."""
        return 1 if self.upper >= self.lower else -1

    @property
    def since(self) -> int:
        """The first window of the change the leading sum has gathered."""
        return self.upper_start if self.direction > 0 else self.lower_start

    def rate(self) -> float:
        """The statistic's change per window since :attr:`since` (its unit per window): the
        slope of a straight line through those windows' values, or the change of the one
        window over the baseline mean."""
        points = [(w, v) for w, v in self.history if w >= self.since]
        if len(points) < 2:
            return (points[-1][1] - self.mean) if points else 0.0
        w, v = np.array(points).T
        return float(np.polyfit(w, v, 1)[0])


def one_sided_tests(cusums: list[Cusum]) -> int:
    """How many one-sided tests the CUSUMs are (a two-sided one counts twice)."""
    return sum(2 if c.two_sided else 1 for c in cusums)
