"""Outliers of a measured run: isolated samples no physical signal can produce.

A sample of the position or the current is an outlier when it departs from the median of its
seven neighbours (itself included) by more than ``OUTLIER_SPREADS`` robust spreads of all such
departures in the run and by more than half the signal's robust range (the 0.1 % to 99.9 %
quantiles): a glitch of the acquisition (``current[1234] = 1e12``), not a breakaway spike, which
spans several samples and stays within the range. Outliers are replaced by that median and
reported; a run with more than the allowed share of them is refused.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

from twin_cosim.measured import MeasuredDataError, MeasuredRun

WINDOW = 7  # samples of the running median
OUTLIER_SPREADS = 50.0  # robust spreads of the departures from the running median
MAD_TO_SIGMA = 1.4826


def _outliers(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the outliers of a signal and the running median that replaces them."""
    median = median_filter(values, size=WINDOW, mode="mirror")
    departure = np.abs(values - median)
    spread = MAD_TO_SIGMA * float(np.median(np.abs(departure - np.median(departure))))
    low, high = np.quantile(values, [0.001, 0.999])
    limit = max(OUTLIER_SPREADS * spread, 0.5 * float(high - low))
    return np.flatnonzero(departure > limit), median


def screen_outliers(run: MeasuredRun, largest_share: float) -> tuple[MeasuredRun, list[str]]:
    """The run with its outliers replaced, and one warning per signal that had any.

    Raises
    ------
    MeasuredDataError
        Naming the file and the column when more than ``largest_share`` of the samples of a
        signal are outliers.
    """
    warnings, replaced = [], {}
    for column in ("x", "current"):
        values = getattr(run, column)
        found, median = _outliers(values)
        if len(found) == 0:
            continue
        shown = ", ".join(f"{column}[{i}] = {values[i]:.4g}" for i in found[:5])
        if len(found) > largest_share * len(values):
            raise MeasuredDataError(
                f"{run.source}: column {column!r}: {len(found)} outliers ({shown}, ...), more "
                f"than {100 * largest_share:g} % of the samples: check the acquisition"
            )
        fixed = values.copy()
        fixed[found] = median[found]
        replaced[column] = fixed
        warnings.append(
            f"{run.source}: {len(found)} outlier(s) in column {column!r} replaced by the median "
            f"of their neighbours before fitting: {shown}"
        )
    return (run.with_signals(replaced) if replaced else run), warnings
