"""Settings of a diagnosis: the split, the thresholds and the effort (one frozen dataclass).

The scenario's ``diagnose`` section may set any field but ``hypotheses``; the command line
overrides ``split`` and ``max_effects``. What each threshold means is said where it is used:
significance in :mod:`twin_cosim.gap.floors.noise` and :mod:`twin_cosim.gap.floors.evidence`,
acceptance in :mod:`twin_cosim.gap.which.acceptance`, the effort of the selection in
:mod:`twin_cosim.gap.which.selector`, localisation in :mod:`twin_cosim.gap.location`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from twin_cosim.scenario import Scenario
from twin_cosim.schema import Checker


@dataclass(frozen=True)
class DiagnosisSettings:
    """Split, thresholds and effort of a diagnosis.

    Attributes
    ----------
    split : float
        Fraction of each measured run used for training when no held-out file is given.
    significance_metric : float
        Least relative error of E_pk, ITAE or IAU (beyond what noise alone makes) that makes
        the held-out gap significant.
    significance_noise : float
        How many standard deviations of the noise-only spread of a metric are added to
        ``significance_metric``.
    significance_level : float
        Level of the test of the held-out residual the best calibration correction leaves
        against noise at the floors (:func:`twin_cosim.gap.floors.evidence.gap_threshold`): the
        gap is significant when it fails that test, or when a figure of merit is off.
    acceptance_level : float
        Family-wise level of the test that a change improves the held-out fit beyond the noise
        (:class:`twin_cosim.gap.which.acceptance.Acceptance`), shared by the changes judged
        together (Bonferroni): a round's hypotheses, its pairs, the swaps or cold refits tried,
        the effects of the backward pass.
    calibration_tolerance : float
        Relative uncertainty of the calibrated parameters (the calibration floor).
    worsen_limit : float
        Largest factor by which an accepted effect may make either signal's held-out RMS worse.
    group_reduction_margin, group_correlation : float
        Two passing effects form a group when their reductions differ by less than the margin
        and their predicted changes correlate at least this much.
    max_effects : int
        Most effects accepted (rounds of selection).
    later_round_candidates : int
        Hypotheses refitted in a later round besides the periodic ones (best of the previous
        round by held-out reduction).
    searched_candidates : int
        Hypotheses of the first round fitted from a global search: every hypothesis is fitted
        locally from its start values first, and the leading ones by training BIC (of those
        whose fit has a search) are fitted again from their search; the others keep their
        local fit.
    pair_candidates : int
        Hypotheses screened in pairs when no single one passes a round: the leading ones by
        training BIC, each pair fitted with the second on top of the first (two effects that
        act in the same place can each make the fit worse alone and pass together).
    joint_candidates : int
        Hypotheses refitted together with the accepted effects when none passes a later round
        on top of them: the leading ones by training BIC (an effect accepted alone can take up
        part of one found later in the same place).
    noise_draws : int
        Draws of white noise at the noise floors used to find what noise alone does to each
        metric.
    outlier_share : float
        Largest share of samples of a run that may be outliers (repaired and reported); a run
        with more is refused.
    axis_bin : float
        Width of the position bins of the along-axis map, m.
    axis_enrichment : float
        Least ratio of a bin's mean residual energy to the median bin's for a bin to count
        as a concentration.
    axis_min_share : float
        Least share of the residual energy above the even level for a span to be named.
    """

    split: float = 0.5
    significance_metric: float = 0.02
    significance_noise: float = 3.0
    significance_level: float = 0.01
    acceptance_level: float = 0.01
    calibration_tolerance: float = 0.03
    worsen_limit: float = 1.1
    group_reduction_margin: float = 0.1
    group_correlation: float = 0.9
    max_effects: int = 3
    later_round_candidates: int = 12
    searched_candidates: int = 4
    pair_candidates: int = 4
    joint_candidates: int = 4
    noise_draws: int = 12
    outlier_share: float = 0.001
    axis_bin: float = 0.5e-3
    axis_enrichment: float = 4.0
    axis_min_share: float = 0.05
    hypotheses: tuple[str, ...] | None = None  # None: the whole library of the plant model


_INTEGER_FIELDS = {
    "max_effects",
    "later_round_candidates",
    "searched_candidates",
    "pair_candidates",
    "joint_candidates",
    "noise_draws",
}


_LEVELS = {"significance_level", "acceptance_level"}  # one-sided levels of a normal test


def settings_from(
    scenario: Scenario, split: float | None = None, max_effects: int | None = None
) -> DiagnosisSettings:
    """Settings from the scenario's ``diagnose`` section, then the command line's overrides.

    Raises
    ------
    ValueError
        Naming the file and the key on an unknown key, a value that is not a finite number, a
        count below 1, a significance level outside (0, 0.5) or a split outside [0.1, 0.9].
    """
    allowed = {f.name for f in dataclasses.fields(DiagnosisSettings) if f.name != "hypotheses"}
    check = Checker(scenario.source)
    section = dict(check.mapping(scenario.diagnose, "diagnose", allowed))
    for key, value in section.items():
        check.number(value, f"diagnose.{key}", minimum=0.0)
        if key in _INTEGER_FIELDS and (value != int(value) or value < 1):
            raise check.fail(f"diagnose.{key}", "a whole number >= 1", value)
        if key in _LEVELS and not 0.0 < value < 0.5:
            raise check.fail(f"diagnose.{key}", "a one-sided level in (0, 0.5)", value)
    if split is not None:
        section["split"] = split
    if max_effects is not None:
        if max_effects < 1:
            raise ValueError(f"--max-effects: expected a whole number >= 1, got {max_effects}")
        section["max_effects"] = max_effects
    if not 0.1 <= section.get("split", 0.5) <= 0.9:
        raise ValueError(f"split: expected a fraction in [0.1, 0.9], got {section['split']}")
    return DiagnosisSettings(
        **{k: int(v) if k in _INTEGER_FIELDS else v for k, v in section.items()}
    )
