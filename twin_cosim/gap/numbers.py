"""Numbers of a diagnosis written for people: three significant digits and a unit.

The report's pages and the command's text use these; the JSON summary keeps full precision.
Lengths and times are shown in the prefix that keeps them readable (2.64e-06 m is 2.64 um);
a missing value is ``-``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

DIGITS = 3
# unit -> (scale, shown unit) from the largest to the smallest prefix
PREFIXES = {
    "m": ((1.0, "m"), (1e3, "mm"), (1e6, "um"), (1e9, "nm")),
    "s": ((1.0, "s"), (1e3, "ms"), (1e6, "us")),
}
DIMENSIONLESS = ("", "1")


def number(value: float | None, digits: int = DIGITS) -> str:
    """``value`` to ``digits`` significant digits: 0.197, 46.1, 1230, 2.64e-06; ``-`` for none.

    Whole numbers as they are (2 samples), positional notation from 1e-3 to below 1e6, powers
    of ten outside.
    """
    if value is None or not math.isfinite(value):
        return "-"
    if float(value).is_integer() and abs(value) < 1e6:
        return str(int(value))
    exponent = math.floor(math.log10(abs(value)))
    if -3 <= exponent < 6:
        decimals = digits - 1 - exponent
        rounded = round(value, decimals)
        if rounded != 0 and math.floor(math.log10(abs(rounded))) > exponent:  # 9.996 -> 10.0
            decimals -= 1
        return f"{rounded:.{max(decimals, 0)}f}"
    return f"{value:.{digits - 1}e}"


def quantity(value: float | None, unit: str) -> str:
    """``value`` (in ``unit``, SI) with its unit, lengths and times in a readable prefix."""
    if unit in DIMENSIONLESS:
        return number(value)
    if value is None or not math.isfinite(value) or value == 0 or unit not in PREFIXES:
        return f"{number(value)} {unit}"
    scale, shown = PREFIXES[unit][-1]
    for factor, name in PREFIXES[unit]:
        if abs(value) * factor >= 1.0:
            scale, shown = factor, name
            break
    return f"{number(value * scale)} {shown}"


def percent(share: float | None) -> str:
    """A share (1 = 100 %) in percent: ``27.4 %``."""
    return "-" if share is None else f"{number(100.0 * share)} %"


def parameters(values: Mapping[str, float], units: Mapping[str, str]) -> str:
    """Fitted parameters: ``stribeck_friction 0.197 N.m, stribeck_speed 0.403 rad/s``; ``-``
    for none."""
    if not values:
        return "-"
    return ", ".join(f"{name} {quantity(v, units.get(name, ''))}" for name, v in values.items())


def names(groups: list[str | list[str]]) -> str:
    """Accepted effects in order: ``stribeck, {current_lag, dead_time}``; ``none``."""
    if not groups:
        return "none"
    return ", ".join(g if isinstance(g, str) else "{" + ", ".join(g) + "}" for g in groups)
