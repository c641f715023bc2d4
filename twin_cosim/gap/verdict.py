"""The verdict of a diagnosis and what is left of the gap, in words and in one table.

What is left is measured on the held-out data after the accepted effects (the final model: all
accepted effects refitted together with the calibrated parameters), beside the same figures
before them (the nominal twin):

- ``energy_share``: the held-out gap energy above the noise left, as a share of what it was,
  (R_after^2 - 1) / (R_before^2 - 1) with R the normalised RMS (1 = noise at the floors);
- ``times_noise_floor``: R_after;
- ``calibration_floor``: the normalised RMS the best calibration correction explains of it, and
  ``beyond_calibration``: what that correction leaves; the two add in quadrature to R_after;
- ``at_floor``: True when what is left after the best calibration correction is not significant
  (it passes the test against noise at the floors and the metrics match within what noise
  makes; :mod:`twin_cosim.gap.floors.evidence`);
- ``floor_position_m``, ``floor_current``: the noise floors themselves (m, A), the unit of the
  normalised figures ("times the noise floor": each signal's residual over its floor);
- ``located_at``: the regimes and spans of the axis where it is concentrated;
- the ``*_before`` fields: the same figures of the nominal twin.

Every number of the text is a cell of :func:`gap_table`, formatted the same way: numbers for
people (:func:`number`, :func:`quantity`, :func:`percent`), three significant digits and a unit.
The report's pages and the command's text use these too; the JSON summary keeps full precision.
Lengths and times are shown in the prefix that keeps them readable (2.64e-06 m is 2.64 um); a
missing value is ``-``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from twin_cosim.gap.floors.evidence import CalibrationFloor
from twin_cosim.gap.location import AxisSpan, Location
from twin_cosim.measured import PositionLabel, compared_label

DIGITS = 3
# unit -> (scale, shown unit) from the largest to the smallest prefix
PREFIXES = {
    "m": ((1.0, "m"), (1e3, "mm"), (1e6, "um"), (1e9, "nm")),
    "rad": ((1.0, "rad"), (1e3, "mrad"), (1e6, "urad")),
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


NAMED_ENRICHMENT = 1.5  # a regime is named where its energy share exceeds its time share so much
NAMED_REGIMES = 2
NAMED_SPANS = 3
DIRECTIONS = {1: "moving +", -1: "moving -", 0: "both directions"}


@dataclass(frozen=True)
class Remaining:
    """What the accepted effects leave of the held-out gap, and what it was before them (see
    the module docstring; RMS in um and A, normalised figures in times the noise floor)."""

    energy_share: float
    times_noise_floor: float
    calibration_floor: float
    beyond_calibration: float
    at_floor: bool
    position_rms_um: float
    current_rms: float
    located_at: str
    text: str
    normalised_rms_before: float
    calibration_floor_before: float
    beyond_calibration_before: float
    significant_before: bool
    position_rms_um_before: float
    current_rms_before: float
    floor_position_m: float
    floor_current: float
    compared: str
    position: PositionLabel


def named_regimes(where: Location) -> list[str]:
    """The regimes where the position residual concentrates, largest energy share first."""
    ordered = sorted(where.position.items(), key=lambda kv: -kv[1]["energy_share"])
    return [name for name, v in ordered[:NAMED_REGIMES] if v["enrichment"] > NAMED_ENRICHMENT]


STROKE_END = "where the axis starts, stops or reverses"


def position_mm(value: float) -> str:
    """A carriage position in mm to the micrometre and three significant digits: ``22.6``,
    ``0.116``, ``0`` (never ``-3.25e-05``)."""
    return number(round(value, 3) + 0.0)


def span_label(span: AxisSpan) -> str:
    """``22.6-23.1 mm along the axis, moving -`` or, for a span at the end of a stroke,
    ``0.116-1.12 mm, moving +, where the axis starts, stops or reverses``."""
    ends = f"{position_mm(span.from_mm)}-{position_mm(span.to_mm)} mm"
    if span.at_stroke_end:
        return f"{ends}, {DIRECTIONS[span.direction]}, {STROKE_END}"
    return f"{ends} along the axis, {DIRECTIONS[span.direction]}"


def _located(where: Location, position: PositionLabel) -> str:
    """The regimes and spans named, with the numbers of their rows in :func:`gap_table`."""
    named = [
        f"{name.replace('_', ' ')} ({percent(where.position[name]['energy_share'])} of the "
        f"{position.words} gap energy, {number(where.position[name]['enrichment'])} x its share "
        "of the time)"
        for name in named_regimes(where)
    ]
    named += [
        f"{span_label(span)} ({'low speed; ' if span.at_stroke_end else ''}"
        f"{percent(span.energy_share)} of the energy above the even level)"
        for span in where.along_axis[:NAMED_SPANS]
    ]
    return "; ".join(named)


def remaining_of(
    before: CalibrationFloor,
    significant_before: bool,
    after: CalibrationFloor,
    significant_left: bool,
    location: Location,
    rms_before: tuple[float, float],
    rms_after: tuple[float, float],
    floors: tuple[float, float],
    compared: str,
    position: PositionLabel,
    by_metrics_only: bool = False,
) -> Remaining:
    """What is left, from the calibration floors of the held-out gap before and after.

    Parameters
    ----------
    before, after
        Calibration floors of the normalised held-out residual of the nominal twin and of the
        final model.
    significant_before, significant_left
        Whether each is a significant gap.
    location
        Where the residual the final model leaves lies.
    rms_before, rms_after
        (position RMS um, current RMS A) of the held-out residual before and after.
    floors
        The noise floors (position m, current A) that normalise the residuals.
    compared
        The signal compared beside the position (``current``, or ``motor_speed`` of open-loop
        runs, rad/s): "current" above stands for it.
    position
        How the position is named and shown (a rotor's angle for open-loop runs): "position"
        and "um" above stand for it.
    by_metrics_only
        Whether what is left is significant only because a figure of merit is off (the
        residual itself passes the test against noise).
    """
    excess_before = max(before.before**2 - 1.0, 0.0)
    share = max(after.before**2 - 1.0, 0.0) / excess_before if excess_before > 0 else 0.0
    where = _located(location, position) if significant_left else ""
    words, unit = compared_label(compared)
    floor_x = quantity(floors[0] * position.per_m, position.si_unit)
    gap_x = f"{number(rms_after[0] * position.per_um)} {position.unit}"
    text = (
        f"Left after the accepted effects: {number(after.before)} times the noise floor (the "
        f"floors: {position.words} {floor_x}, {words} {quantity(floors[1], unit)} "
        f"RMS), {percent(share)} of the held-out gap energy above the noise; a held-out gap "
        f"of {gap_x} RMS in {position.words} and {number(rms_after[1])} {unit} RMS "
        f"in {words}. Of these {number(after.before)} times the noise floor, calibration error "
        f"within tolerance can explain {number(after.explained)} and leaves "
        f"{number(after.left)} (the two add in quadrature)"
    )
    if significant_left:
        text += ": a significant gap"
        text += " (E_pk, ITAE or IAU off beyond what noise makes)" if by_metrics_only else ""
        text += f", located at: {where}." if where else "."
    else:
        text += ", which is not significant: what is left is noise and calibration error."
    return Remaining(
        share,
        after.before,
        after.explained,
        after.left,
        not significant_left,
        rms_after[0],
        rms_after[1],
        where,
        text,
        before.before,
        before.explained,
        before.left,
        significant_before,
        rms_before[0],
        rms_before[1],
        floors[0],
        floors[1],
        compared,
        position,
    )


GAP_TABLE_HEADER = ["held-out gap", "before the accepted effects", "after the accepted effects"]


def gap_table(
    remaining: Remaining, before_shares: dict[str, dict[str, float]], where: Location
) -> list[list[str]]:
    """The verdict's table: every number of :attr:`Remaining.text`, before and after.

    Parameters
    ----------
    remaining
        What is left.
    before_shares
        Position residual shares per regime of the held-out gap before the effects
        (:func:`twin_cosim.gap.data.regimes.energy_shares`).
    where
        Where what is left lies (the after column of the regimes; the spans).
    """
    r = remaining
    words, unit = compared_label(r.compared)
    x = r.position
    floor_x = quantity(r.floor_position_m * x.per_m, x.si_unit)
    floor_i = quantity(r.floor_current, unit)
    rows = [
        [f"noise floor of the {x.words} (RMS)", floor_x, floor_x],
        [f"noise floor of the {words} (RMS)", floor_i, floor_i],
        [
            f"{x.words} gap, RMS [{x.unit}]",
            number(r.position_rms_um_before * x.per_um),
            number(r.position_rms_um * x.per_um),
        ],
        [f"{words} gap, RMS [{unit}]", number(r.current_rms_before), number(r.current_rms)],
        [
            "normalised RMS of both [times the noise floor]",
            number(r.normalised_rms_before),
            number(r.times_noise_floor),
        ],
        ["gap energy above the noise [% of before]", percent(1.0), percent(r.energy_share)],
        [
            "of the normalised RMS: explained by calibration error within tolerance "
            "[times the noise floor, in quadrature]",
            number(r.calibration_floor_before),
            number(r.calibration_floor),
        ],
        [
            "of the normalised RMS: left beyond calibration error "
            "[times the noise floor, in quadrature]",
            number(r.beyond_calibration_before),
            number(r.beyond_calibration),
        ],
        [
            "significant beyond noise and calibration error",
            "yes" if r.significant_before else "no",
            "no" if r.at_floor else "yes",
        ],
    ]
    for name in named_regimes(where) if not r.at_floor else []:
        label = name.replace("_", " ")
        rows.append(
            [
                f"{label}: share of the {x.words} gap energy [%]",
                percent(before_shares[name]["energy_share"]),
                percent(where.position[name]["energy_share"]),
            ]
        )
        rows.append(
            [
                f"{label}: energy share over its share of the time [x]",
                number(before_shares[name]["enrichment"]),
                number(where.position[name]["enrichment"]),
            ]
        )
    for span in where.along_axis[:NAMED_SPANS] if not r.at_floor else []:
        rows.append(
            [
                f"span {span_label(span)}: share of the energy above the even level [%]",
                "-",
                percent(span.energy_share),
            ]
        )
    return [GAP_TABLE_HEADER, *rows]


def verdict_text(
    significant: bool,
    accepted: list[list[str]],
    within_calibration: list[str],
    remaining: Remaining,
) -> str:
    """One paragraph: a short first sentence (significant or not, what explains it), then what
    is left (:attr:`Remaining.text`). ``within_calibration``: the first round's hypotheses that
    explain much of a gap none passed, and failed a test against calibration error (the
    tolerance, or the gain once the corrections are replayed)."""
    if not significant:
        return (
            "no significant gap. Beyond noise and calibration error within tolerance, the twin's "
            "E_pk, ITAE and IAU match the measured ones within the significance threshold."
        )
    if accepted:
        found = names([g if len(g) > 1 else g[0] for g in accepted])
        if remaining.at_floor:
            return f"significant gap, explained: {found}. {remaining.text}"
        return f"significant gap, explained in part: {found}. {remaining.text}"
    if within_calibration:
        return (
            "significant gap, not diagnosable beyond calibration error. The effects that explain "
            f"it ({', '.join(within_calibration)}) do not go beyond what calibration error within "
            "the tolerance explains (the first round's ranking names the tests each failed). "
            f"{remaining.text}"
        )
    return (
        "significant gap that no effect of the library explains on held-out data. See 'where' "
        f"for its location. {remaining.text}"
    )
