"""The verdict of a diagnosis and what is left of the gap, in words and numbers.

What is left is measured on the held-out data after the accepted effects:

- ``energy_share``: the held-out gap energy above the noise left, as a share of what it was,
  (R_after^2 - 1) / (R_before^2 - 1) with R the normalised RMS (1 = noise at the floors);
- ``times_noise_floor``: R_after;
- ``calibration_floor``: the normalised RMS the best calibration correction explains of it, and
  ``beyond_calibration``: what that correction leaves;
- ``at_floor``: True when what is left after the best calibration correction is not significant
  (it passes the test against noise at the floors and the metrics match within what noise
  makes; :mod:`twin_cosim.gap.evidence`);
- ``located_at``: the regimes and spans of the axis where it is concentrated.
"""

from __future__ import annotations

from dataclasses import dataclass

from twin_cosim.gap.calibration import CalibrationFloor
from twin_cosim.gap.location import Location


@dataclass(frozen=True)
class Remaining:
    """What the accepted effects leave of the held-out gap (see the module docstring)."""

    energy_share: float
    times_noise_floor: float
    calibration_floor: float
    beyond_calibration: float
    at_floor: bool
    position_rms_um: float
    current_rms: float
    located_at: str
    text: str


def remaining_of(
    before_rms: float,
    floor: CalibrationFloor,
    significant_left: bool,
    location: Location,
    position_rms_um: float,
    current_rms: float,
) -> Remaining:
    """What is left, from the normalised RMS before the effects and the floor after them."""
    after = floor.before
    excess_before = max(before_rms**2 - 1.0, 0.0)
    share = max(after**2 - 1.0, 0.0) / excess_before if excess_before > 0 else 0.0
    where = location.describe() if significant_left else ""
    text = (
        f"left: {100 * share:.1f} % of the held-out gap energy above the noise, "
        f"{after:.3g} times the noise floor (position {position_rms_um:.4g} um RMS, current "
        f"{current_rms:.4g} A RMS); calibration error within tolerance can explain "
        f"{floor.explained:.3g} of it and leaves {floor.left:.3g} times the noise floor"
    )
    if significant_left:
        text += ", a significant gap" + (f", located at: {where}" if where else "")
    else:
        text += ", which is not significant: what is left is noise and calibration error"
    return Remaining(
        share,
        after,
        floor.explained,
        floor.left,
        not significant_left,
        position_rms_um,
        current_rms,
        where,
        text,
    )


def verdict_text(
    significant: bool,
    accepted: list[list[str]],
    below_tolerance: list[str],
    remaining: Remaining,
) -> str:
    """One paragraph: significant or not, what explains it, what is left."""
    if not significant:
        return (
            "no significant gap: beyond noise and calibration error within tolerance, the twin's "
            "E_pk, ITAE and IAU match the measured ones within the significance threshold"
        )
    if accepted:
        names = ", ".join("{" + ", ".join(g) + "}" if len(g) > 1 else g[0] for g in accepted)
        if remaining.at_floor:
            return f"significant gap, explained: {names}; {remaining.text}"
        return (
            f"significant gap, explained in part: {names}; a significant part is left "
            f"unexplained; {remaining.text}"
        )
    if below_tolerance:
        return (
            f"significant gap, but the effects that explain it ({', '.join(below_tolerance)}) "
            "are smaller than the calibration tolerance: not diagnosable beyond calibration "
            f"error; {remaining.text}"
        )
    return (
        "significant gap that no effect of the library explains on held-out data: "
        f"see 'where' for its location; {remaining.text}"
    )
