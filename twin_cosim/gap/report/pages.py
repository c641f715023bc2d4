"""The diagnosis' files: ``diagnosis.json`` (its summary), ``report.md`` and ``report.html``
(the pages), ``plant.yaml`` and ``calibrated.yaml`` (its calibrated plant, and the diagnosed
scenario with it folded in), each written from the typed
:class:`~twin_cosim.gap.diagnosis.Diagnosis`; :func:`summary` is its one serialisation to JSON.

The figures are drawn apart, after the pages (:mod:`twin_cosim.gap.report.figures`).
"""

from __future__ import annotations

import dataclasses
import html
import json
import re
from collections.abc import Callable
from dataclasses import asdict
from operator import attrgetter
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin_cosim.gap.data.context import library_for
from twin_cosim.gap.data.regimes import energy_shares
from twin_cosim.gap.diagnosis import Diagnosis, HeldOutRun, jsonable
from twin_cosim.gap.verdict import (
    STROKE_END,
    gap_table,
    names,
    number,
    parameters,
    percent,
    position_mm,
    quantity,
)
from twin_cosim.gap.which.acceptance import JointCandidate
from twin_cosim.gap.which.selector import correlation
from twin_cosim.measured import PositionLabel, compared_label
from twin_cosim.plant_model import DRIVE_FACTS, plant_model
from twin_cosim.scenario.plant_parameters import calibrated_scenario, write_plant_parameters
from twin_cosim.versions import versions

if TYPE_CHECKING:
    from twin_cosim.gap.floors.noise import MetricComparison
    from twin_cosim.gap.which.acceptance import Candidate, Judgement, Pair
    from twin_cosim.gap.which.selector import Refit, Round, Swap


Column = tuple[str, Callable[[Any], str]]


def _table(rows: list[Any], columns: list[Column]) -> list[list[str]]:
    """Header and cells, each cell written by its column's formatter of the row."""
    return [[label for label, _ in columns]] + [[show(row) for _, show in columns] for row in rows]


def summary(d: Diagnosis) -> dict[str, Any]:
    """The diagnosis as JSON-ready data (``diagnosis.json``, ``--json``): the one place it is
    serialised."""
    selection = d.selection
    first = next((r for r in d.rounds if r.candidates), None)
    last = next((r for r in reversed(d.rounds) if r.candidates), None)
    swapped_out = [w.removed for w in selection.swaps if w.kept]
    steps = [_step(r, selection.dropped, swapped_out) for r in d.steps]
    held = d.held_out_runs
    gap = {
        "significant": d.significant,
        "holdout_normalised_rms": d.rounds[0].holdout_rms,
        "verdict": d.verdict,
        "validation_figures": d.validation,
        "holdout_metrics_before": _metric_row(d.metrics_before[0]),
        "holdout_metrics_after": _metric_row(d.metrics_after[0]),
        "unexplained_share_by_regime": d.unexplained_by_regime,
        "remaining": asdict(d.remaining),
        "holdout_runs": [asdict(h) for h in held],
        "holdout_relative_errors_before": _combined(held, "relative_errors_before"),
        "holdout_relative_errors_after": _combined(held, "relative_errors_after"),
        "model_error": None if (e := d.calibrated_plant.model_error) is None else e.as_dict(),
    }
    context = d.context
    return jsonable(
        {
            "scenario": str(context.scenario.source),
            "model": context.model,
            "measured": context.measured,
            "holdout": context.holdout or context.split,
            "split": context.split,
            "accepted": d.accepted,
            "marginal": [asdict(m) for m in selection.marginal],
            "dropped": selection.dropped,
            "swaps": [_swap_row(w) for w in selection.swaps],
            "refits": [_refit_row(r) for r in selection.refits],
            "steps": steps,
            "effects": [_row(c, first) for c in first.candidates] if first else [],
            "last_round": [_row(c, last) for c in last.candidates] if last else [],
            "rounds": [_round(r) for r in d.rounds],
            "where": {
                "position": d.where.position,
                "current": d.where.current,
                "along_axis": [asdict(s) for s in d.where.along_axis],
            },
            "periodicity": d.where.periodicity,
            "gap": gap,
            "noise": {
                "harmonics": [asdict(h) for h in d.noise.harmonics],
                "dropped": d.noise.dropped,
                "plant_parameters": d.noise.plant_parameters,
                "sigma_position_um": d.floors.sigma_position_m * 1e6,
                "sigma_current_A": d.floors.sigma_current,
                "floor_sources": {
                    "position": d.floors.position_source,
                    "current": d.floors.current_source,
                },
            },
            "context": d.rounds[0].context,
            "thresholds": asdict(d.settings),
            "warnings": d.warnings,
            "final_plant_parameters": selection.plant_parameters,
            "time": d.times,
        }
    )


def _picked(source: Any, *names: str) -> dict[str, Any]:
    """Attributes of ``source``, in the order named: ``name`` (the key is the attribute's name)
    or ``key=path`` (the attribute at a dotted path, e.g. ``params=fit.values``)."""
    entries = (name.partition("=") for name in names)
    return {key: attrgetter(path or key)(source) for key, _, path in entries}


def _metric_row(c: MetricComparison) -> dict[str, Any]:
    """A held-out run's figures of merit, measured and the twin's, and whether they are off."""
    return _picked(
        c,
        *("run", "measured", "twin", "relative_error", "noise_spread", "threshold"),
        *("largest_relative_error", "off"),
    )


def _acceptance_tests(j: Judgement) -> dict[str, Any]:
    """What a candidate's acceptance tests measured (a round's candidates and a swap's rival)."""
    return {
        **_picked(j, "holdout_reduction=reduction", "reduction_beyond_calibration"),
        **asdict(j.gain),  # evidence z, critical z, excess share, fair share
        "size_above_tolerance": j.size_above_tolerance,
        "with_corrections_replayed": None if j.replayed is None else asdict(j.replayed),
    }


def _fitted(c: Candidate) -> dict[str, Any]:
    """A candidate's fit: its hypothesis, values, training cost and BIC, replays."""
    return _picked(
        c, "name", "params=fit.values", "train_cost=fit.train_cost", "bic", "replays=fit.replays"
    )


def _held_out_gaps(before: Round, after: Judgement) -> dict[str, Any]:
    """The held-out position and current RMS before a candidate (its round's) and with it."""
    return {
        "holdout_gap_before_um": before.position_rms_um,
        "holdout_gap_after_um": after.position_rms_um,
        "holdout_current_before_A": before.current_rms,
        "holdout_current_after_A": after.current_rms,
    }


def _row(c: Candidate, round_: Round) -> dict[str, Any]:
    judged = c.judgement
    return {
        **_fitted(c),
        **_held_out_gaps(round_, judged),
        **_acceptance_tests(judged),
        "explained_normalised_rms": judged.explained,
        "calibration_floor_normalised_rms": round_.calibration.explained,
        "consistent": judged.consistent,
        "passes": c.passes,
    }


def _step(r: Round, dropped: list[str], swapped_out: list[str]) -> dict[str, Any]:
    best = r.best
    assert best is not None
    judged = best.judgement
    return {
        "round": r.index,
        "effect": r.effect,
        "together": list(r.pair.members) if r.pair else [],
        "refitted_with_the_accepted": isinstance(best, JointCandidate),
        "fitted": best.name,
        "params": best.fit.values,
        "plant_parameters": best.fit.overrides,
        "context": r.context,
        **_held_out_gaps(r, judged),
        "holdout_normalised_rms_before": r.holdout_rms,
        "holdout_normalised_rms_after": judged.holdout_rms,
        **_picked(judged, "reduction", "reduction_beyond_calibration"),
        **_picked(judged.gain, "evidence_z", "critical_z", "excess_share"),
        "dropped_in_backward_pass": best.name in dropped,
        "swapped_out": best.name in swapped_out,
        "ranking": [_row(c, r) for c in r.candidates],
    }


def _swap_row(w: Swap) -> dict[str, Any]:
    """A swap tried: the effect taken out, the rival put in with its fit and its acceptance
    tests against the model as it was, and whether the swap was made."""
    c = w.candidate
    judged = c.judgement
    return {
        "removed": w.removed,
        **_fitted(c),
        **_picked(
            judged,
            "holdout_normalised_rms_after=holdout_rms",
            "holdout_gap_after_um=position_rms_um",
            "holdout_current_after_A=current_rms",
        ),
        **_acceptance_tests(judged),
        "consistent": judged.consistent,
        "passes": c.passes,
        "kept": w.kept,
    }


def _refit_row(r: Refit) -> dict[str, Any]:
    """A cold refit that replaced its effect, and its gain against the rule."""
    return {
        **_picked(r, "effect", "values_before", "values_after", "left_before", "left_after"),
        **asdict(r.gain),
        "significant": r.significant,
    }


def _round(r: Round) -> dict[str, Any]:
    return {
        "round": r.index,
        "significant": r.significant,
        "context": r.context,
        "holdout_normalised_rms": r.holdout_rms,
        "calibration": asdict(r.calibration),
        "metrics_after_calibration": [_metric_row(m) for m in r.metrics],
        "fitted": [c.name for c in r.candidates],
        "accepted": r.accepted,
        "joint": [_row(c, r) for c in r.joint],
        "pairs": [_pair_row(p, r) for p in r.pairs],
    }


def _pair_row(p: Pair, round_: Round) -> dict[str, Any]:
    """A screened pair: its row as a candidate's, and what each member adds to the other."""
    return {**_row(p, round_), "members": list(p.members), "within": [asdict(m) for m in p.within]}


def _combined(runs: list[HeldOutRun], key: str) -> dict[str, float]:
    """One figure per signal over all held-out runs (the first run's when there is one)."""
    if not runs:
        return {}
    if len(runs) == 1:
        return getattr(runs[0], key)
    names = getattr(runs[0], key).keys()
    return {n: float(np.sqrt(np.mean([getattr(r, key)[n] ** 2 for r in runs]))) for n in names}


def _text(value: Any) -> str:
    return "-" if value is None else str(value).replace("_", " ")


def _yes(value: Any) -> str:
    return "yes" if value else "no"


def _ranking_columns(
    units: dict[str, dict[str, str]], compared: str, position: PositionLabel
) -> list[Column]:
    """The columns of a round's ranking (one row per :class:`Candidate`); ``compared``: the
    signal compared beside the position, ``position``: how the position is shown."""
    words, unit = compared_label(compared)
    x = position

    def fitted(c: Candidate) -> str:
        return parameters(c.fit.values, units.get(c.name, {}))

    return [
        ("hypothesis", lambda c: _text(c.name)),
        ("fitted parameters", fitted),
        ("training BIC", lambda c: number(c.bic)),
        (
            f"held-out {x.words} RMS with it [{x.unit}]",
            lambda c: number(c.judgement.position_rms_um * x.per_um),
        ),
        (f"held-out {words} RMS with it [{unit}]", lambda c: number(c.judgement.current_rms)),
        ("reduction of the normalised RMS", lambda c: percent(c.judgement.reduction)),
        ("evidence z", lambda c: number(c.judgement.gain.evidence_z)),
        ("needed z", lambda c: number(c.judgement.gain.critical_z)),
        ("share of the energy above the noise", lambda c: percent(c.judgement.gain.excess_share)),
        ("fair share", lambda c: percent(c.judgement.gain.fair_share)),
        ("share with the corrections replayed", _replayed_share),
        ("passes", lambda c: "yes" if c.passes else f"no: {', '.join(c.judgement.failed)}"),
    ]


def _replayed_share(c: Candidate) -> str:
    """The share of the excess energy a candidate removes with the calibration corrections
    replayed, where that was asked ("-" elsewhere)."""
    replayed = c.judgement.replayed
    return "-" if replayed is None else percent(replayed.excess_share)


def _step_columns(
    units: dict[str, dict[str, str]], compared: str, position: PositionLabel
) -> list[Column]:
    """The columns of the accepted effects (one row per :class:`Round` that accepted one);
    ``compared``: the signal compared beside the position, ``position``: how the position is
    shown."""
    words, unit = compared_label(compared)
    x = position

    def best(r: Round) -> Candidate:
        assert r.best is not None
        return r.best

    def fitted(r: Round) -> str:
        return parameters(best(r).fit.values, units.get(best(r).name, {}))

    return [
        ("accepted", lambda r: names([r.effect])),
        ("fitted parameters (its round)", fitted),
        (
            f"held-out {x.words} RMS before it [{x.unit}]",
            lambda r: number(r.position_rms_um * x.per_um),
        ),
        (
            f"with it, as fitted in its round [{x.unit}]",
            lambda r: number(best(r).judgement.position_rms_um * x.per_um),
        ),
        (f"held-out {words} RMS before it [{unit}]", lambda r: number(r.current_rms)),
        (
            f"with it, as fitted in its round [{unit}]",
            lambda r: number(best(r).judgement.current_rms),
        ),
        ("reduction of the normalised RMS", lambda r: percent(best(r).judgement.reduction)),
    ]


SHARE_COLUMNS: list[Column] = [  # rows: (regime, its shares)
    ("regime", lambda row: _text(row[0])),
    ("share of the time [%]", lambda row: percent(row[1]["time_share"])),
    ("share of the residual energy [%]", lambda row: percent(row[1]["energy_share"])),
    ("energy share over time share [x]", lambda row: number(row[1]["enrichment"])),
]
AXIS_COLUMNS: list[Column] = [  # rows: AxisSpan
    ("from [mm]", lambda span: position_mm(span.from_mm)),
    ("to [mm]", lambda span: position_mm(span.to_mm)),
    ("direction of motion", lambda span: {1: "+", -1: "-", 0: "both"}.get(span.direction, "-")),
    (STROKE_END, lambda span: _yes(span.at_stroke_end)),
    ("share of the energy above the even level [%]", lambda span: percent(span.energy_share)),
    ("peak energy over the even level [x]", lambda span: number(span.enrichment)),
]


def _axis_sections(d: Diagnosis) -> list[tuple[str, str | list[list[str]]]]:
    """The spans along the axis where the residual is concentrated, before and after the
    accepted effects; for a rotor, which turns without travel, why there are none."""
    if not d.context.position_label.travel:
        return [
            (
                "Along the axis",
                "An open-loop rotor turns without travel along an axis: no span of an axis is "
                "named. Its residual is placed by regime (above) and by orders of its angle "
                "(below).",
            )
        ]
    return [
        (
            "Before the accepted effects: spans along the axis where the residual is concentrated",
            _table(d.where.along_axis, AXIS_COLUMNS)
            if d.where.along_axis
            else "The residual is spread evenly along the axis: no span stands out.",
        ),
        (
            "After the accepted effects (held-out data): spans along the axis",
            _table(d.remaining_where.along_axis, AXIS_COLUMNS)
            if d.remaining_where.along_axis
            else "What is left is spread evenly along the axis: no span stands out.",
        ),
    ]


def lookalikes(d: Diagnosis) -> str:
    """Each accepted look-alike group: why its members count as one (the round's figures) and
    which member's fit the calibrated plant holds."""
    settings, units = d.settings, hypothesis_units(d.context.model)
    texts = []
    for step in d.steps:
        group = step.accepted if step.pair is None else []
        members = [c for name in group for c in step.candidates if c.name == name]
        if len(members) < 2:
            continue
        first = members[0]
        reductions = " and ".join(percent(c.judgement.reduction) for c in members)
        agreement = ", ".join(
            number(correlation(c.judgement.change, first.judgement.change)) for c in members[1:]
        )
        texts.append(
            f"{names([group])}: in round {step.index} each passed every held-out test; their "
            f"reductions of the normalised RMS ({reductions}) differ by less than "
            f"{100 * settings.group_reduction_margin:g} percentage points and the "
            f"changes they predict on the held-out data correlate with the first's at "
            f"{agreement} (at least {settings.group_correlation:g}), so the data "
            "cannot tell them apart. The group is named as one; the calibrated plant holds the "
            "fit of its first, "
            f"{first.name} ({parameters(first.fit.values, units.get(first.name, {}))})."
        )
    return " ".join(texts)


def _errors(value: dict[str, float]) -> str:
    return ", ".join(f"{k} {percent(v / 100.0)}" for k, v in value.items()) or "-"


def _pulses(value: dict[str, float] | None) -> str:
    if not value:
        return "-"
    return (
        f"{value['edges']} edges: {percent(value['energy_share'])} of the energy in "
        f"{percent(value['time_share'])} of the time, ringing at {number(value['ringing_hz'])} Hz"
    )


def _run_columns(runs: list[HeldOutRun], compared: str, position: PositionLabel) -> list[Column]:
    """The columns of the held-out runs (one row per :class:`HeldOutRun`); ``compared``: the
    signal compared beside the position, ``position``: how the position is shown."""
    words, unit = compared_label(compared)
    x = position
    columns: list[Column] = [
        ("held-out run", lambda r: r.source),
        (
            f"{x.words} RMS before [{x.unit}]",
            lambda r: number(r.position_rms_um_before * x.per_um),
        ),
        (f"after [{x.unit}]", lambda r: number(r.position_rms_um_after * x.per_um)),
        (f"{words} RMS before [{unit}]", lambda r: number(r.current_rms_before)),
        (f"after [{unit}]", lambda r: number(r.current_rms_after)),
        ("relative errors before", lambda r: _errors(r.relative_errors_before)),
        ("after", lambda r: _errors(r.relative_errors_after)),
    ]
    if any(r.pulse_response_before for r in runs):
        columns += [
            (
                "acceleration residual after pulse edges, before",
                lambda r: _pulses(r.pulse_response_before),
            ),
            ("after", lambda r: _pulses(r.pulse_response_after)),
        ]
    return columns


def hypothesis_units(model: str) -> dict[str, dict[str, str]]:
    """Unit of each fitted parameter, per hypothesis of the model's library."""
    return {h.name: {p.name: p.unit for p in h.parameters} for h in library_for(model)}


def _parameter_units(model: str) -> dict[str, str]:
    """Unit of each FMU parameter of the model."""
    return {name: v.unit or "" for name, v in plant_model(model).parameters.items()}


def _metrics(values: dict[str, float]) -> str:
    return " / ".join(percent(v) for v in values.values())


def _validation(d: Diagnosis, position: PositionLabel) -> str:
    """The paper's validation figures of the gap before the accepted effects, and the held-out
    relative errors of E_pk / ITAE / IAU (a run in closed loop: an open-loop run follows no
    reference and has none)."""
    x, figures = position, d.validation
    text = (
        f"max |gap| {number(figures['max_um'] * x.per_um)} {x.unit}, mean |gap| "
        f"{number(figures['mean_abs_um'] * x.per_um)} {x.unit}, RMS "
        f"{number(figures['rms_um'] * x.per_um)} {x.unit}."
    )
    before, after = d.metrics_before[0], d.metrics_after[0]
    if not before.relative_error:
        return text + " No E_pk / ITAE / IAU: the runs are open loop (no reference they follow)."
    return (
        f"{text} Held-out relative errors of E_pk / ITAE / IAU before: "
        f"{_metrics(before.relative_error)}; after: {_metrics(after.relative_error)} "
        f"(significant above {_metrics(before.threshold)}: "
        f"{percent(d.settings.significance_metric)} plus what noise alone makes)."
    )


def _model_error_section(d: Diagnosis, x: PositionLabel) -> list[tuple[str, str]]:
    """What the calibrated twin (``plant.yaml`` replayed as written) still misses on the
    held-out runs: the margins of a prediction's interval; none for open-loop runs."""
    error = d.calibrated_plant.model_error
    if error is None:
        return []
    words, unit = compared_label(d.context.compared)  # the current, or a drive's command (V)
    return [
        (
            "What the calibrated twin still misses on the held-out runs (plant.yaml, model_error)",
            f"{x.words}: largest {quantity(error.position_peak_m * x.per_m, x.si_unit)}, RMS "
            f"{quantity(error.position_rms_m * x.per_m, x.si_unit)}; {words}: RMS "
            f"{quantity(error.current_rms_A, unit)}. A prediction of E_pk, ITAE and IAU for other "
            "gains (twin simulate --machine with --plant-parameters plant.yaml) widens its "
            "interval by the bounds these set on one run (twin_cosim.model_error), assuming the "
            "twin misses no more there.",
        )
    ]


def _setting(name: str, value: Any) -> str:
    """A setting as a person reads it: ``0.5``, ``500 um``, ``the whole library``."""
    if value is None:
        return "the whole library"
    if isinstance(value, (tuple, list)):
        return ", ".join(str(v) for v in value)
    if name in SETTING_UNITS:
        return quantity(value, SETTING_UNITS[name])
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


SETTING_UNITS = {"axis_bin": "m"}


def sections(d: Diagnosis) -> list[tuple[str, str | list[list[str]]]]:
    """The report as (heading, text or table) pairs, shared by Markdown and HTML.

    Every number is written for people (:mod:`twin_cosim.gap.verdict`); the verdict is
    followed by the table that holds each of its numbers (:func:`gap_table`).
    """
    units = hypothesis_units(d.context.model)
    compared_words, compared_unit = compared_label(d.context.compared)
    x = d.context.position_label
    first = next((r for r in d.rounds if r.candidates), None)
    verdict = d.verdict
    if d.remaining.text not in verdict:
        verdict += f" {d.remaining.text}"
    before_shares = energy_shares(d.holdout_before.position, d.holdout_before.regimes)
    noise = parameters(d.noise.plant_parameters, _parameter_units(d.context.model))
    parts: list[tuple[str, str | list[list[str]]]] = [
        ("Verdict", verdict),
        (
            "The verdict's figures: the held-out gap before and after the accepted effects "
            "(after: all accepted effects refitted together with the calibrated parameters)",
            gap_table(d.remaining, before_shares, d.remaining_where),
        ),
        (
            "Data",
            f"Scenario {d.context.scenario.source}; plant model {d.context.model}; measured "
            f"{', '.join(d.context.measured)}; split: {d.context.split}.",
        ),
        (
            "Noise floors",
            f"{x.words} {quantity(d.floors.sigma_position_m * x.per_m, x.si_unit)} "
            f"({d.floors.position_source}); "
            f"{compared_words} {quantity(d.floors.sigma_current, compared_unit)} "
            f"({d.floors.current_source}).",
        ),
        (
            "Validation figures (training and held-out data before the accepted effects, as in "
            "the paper)",
            _validation(d, x),
        ),
        (
            "Held-out runs, before and after the accepted effects",
            _table(d.held_out_runs, _run_columns(d.held_out_runs, d.context.compared, x)),
        ),
        *_model_error_section(d, x),
        (
            "Where the gap lies before the accepted effects (training and held-out data): "
            f"{x.words} residual by regime",
            _table(list(d.where.position.items()), SHARE_COLUMNS),
        ),
        (
            f"Before the accepted effects: {compared_words} residual by regime",
            _table(list(d.where.current.items()), SHARE_COLUMNS),
        ),
        *_axis_sections(d),
        (
            "Before the accepted effects: position-periodic or temporal (a speed group: the "
            "constant-velocity stretches at one speed level, within 10 %; a peak at a fixed "
            "order across the groups, its frequency moving, is position-periodic)",
            "; ".join(
                f"{k.replace('current_', compared_words + '_').replace('_', ' ')}: "
                f"{v['verdict']} ({v['reason']})"
                for k, v in d.where.periodicity.items()
            ),
        ),
        (
            "Which: hypotheses fitted on the training data, judged on the held-out data (first "
            f"round; held-out {x.words} RMS before "
            f"{number(d.rounds[0].position_rms_um * x.per_um)} {x.unit}, "
            f"{compared_words} {number(d.rounds[0].current_rms)} {compared_unit})",
            _table(
                first.candidates if first else [],
                _ranking_columns(units, d.context.compared, x),
            ),
        ),
        *(
            [("Look-alike groups (a name in braces)", lookalikes(d))]
            if any(len(g) > 1 for g in d.accepted)
            else []
        ),
        (
            "How far: each accepted effect on the held-out data, as fitted in its round",
            _table(d.steps, _step_columns(units, d.context.compared, x))
            if d.steps
            else "No effect passed the held-out test.",
        ),
        (
            f"Share of the held-out {x.words} gap energy left after the accepted effects, by "
            "regime",
            ", ".join(
                f"{k.replace('_', ' ')} {percent(v)}" for k, v in d.unexplained_by_regime.items()
            ),
        ),
        (
            "Noise model (Fourier series at standstill; add to the scenario's plant.parameters)",
            ("none identified" if noise == "-" else noise)
            + (f"; dropped: {'; '.join(d.noise.dropped)}" if d.noise.dropped else ""),
        ),
        (
            "Thresholds (DiagnosisSettings; the scenario's diagnose: section)",
            [["setting", "value"]] + [[k, _setting(k, v)] for k, v in asdict(d.settings).items()],
        ),
        ("Warnings", "; ".join(d.warnings) or "none"),
    ]
    return parts


STYLE = (
    "body{font-family:sans-serif;max-width:72em;margin:1em auto;padding:0 1em;line-height:1.4}"
    "h2{font-size:1.1em;margin-top:1.6em}"
    "table{border-collapse:collapse;font-size:0.9em}"
    "th,td{border:1px solid #bbb;padding:0.2em 0.5em;vertical-align:top}"
    "th{background:#eee;text-align:left}td.n{text-align:right;white-space:nowrap}"
    ".verdict{background:#f4f4f4;border-left:4px solid #555;padding:0.6em 0.8em}"
    "img{max-width:100%}"
)
NUMERIC = re.compile(r"^(-|[-+]?\d[\d.e+-]*( %)?|yes|no)$")


def _html_table(rows: list[list[str]]) -> str:
    """A table: a header row, then cells; numbers right-aligned."""
    header = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join(
        "<tr>"
        + "".join(f"<td{' class=n' if NUMERIC.match(c) else ''}>{html.escape(c)}</td>" for c in row)
        + "</tr>"
        for row in rows[1:]
    )
    return f"<table><tr>{header}</tr>{body}</table>"


FIGURES = ("residuals.png", "regimes.png", "along_axis.png", "spectra.png", "ranking.png")


def write_report(
    d: Diagnosis,
    out: Path,
    summary: dict[str, Any],
    command: str,
    figures: bool = True,
) -> dict[str, str]:
    """Write the diagnosis' files into ``out``: diagnosis.json (``summary``: the diagnosis'
    :func:`summary` and what the command adds), report.md
    and report.html, plant.yaml (its calibrated plant, made by ``command`` and this version)
    and calibrated.yaml (the diagnosed scenario with it).

    The pages show :data:`FIGURES` when ``figures`` (written apart, after the pages:
    :func:`twin_cosim.gap.report.figures.write_figures`).

    Returns
    -------
    dict
        Paths of the files written: ``json``, ``markdown``, ``html``, ``plant`` and
        ``calibrated``.
    """
    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnosis.json").write_text(json.dumps(summary, indent=2) + "\n")
    parts = sections(d)
    markdown = ["# Sim-to-real gap diagnosis", ""]
    page = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>Gap diagnosis</title><style>{STYLE}</style></head><body>",
        "<h1>Sim-to-real gap diagnosis</h1>",
    ]
    for index, (heading, body) in enumerate(parts):
        markdown += [f"## {heading}", ""]
        page.append(f"<h2>{html.escape(heading)}</h2>")
        if isinstance(body, str):
            markdown += [body, ""]
            page.append(f"<p{' class=verdict' if index == 0 else ''}>{html.escape(body)}</p>")
        else:
            markdown += ["| " + " | ".join(body[0]) + " |", "|" + "---|" * len(body[0])]
            markdown += ["| " + " | ".join(row) + " |" for row in body[1:]] + [""]
            page.append(_html_table(body))
    if figures:
        markdown += ["## Figures", ""] + [f"![{name}]({name})" for name in FIGURES] + [""]
        page += ["<h2>Figures</h2>"]
        page += [f"<p><img src='{name}' alt='{name}'></p>" for name in FIGURES]
    page.append("</body></html>")
    (out / "report.md").write_text("\n".join(markdown))
    (out / "report.html").write_text("\n".join(page) + "\n")
    plant = d.calibrated_plant
    made = {**plant.created_by, "command": command, "version": versions()["twin-cosim"]}
    plant = dataclasses.replace(plant, created_by=made)
    plant_file = write_plant_parameters(out / "plant.yaml", plant)
    scenario = d.context.scenario
    drive = {name: getattr(scenario.settings, name) for name in DRIVE_FACTS}
    calibrated = calibrated_scenario(scenario.source, plant, out / "calibrated.yaml", drive)
    return {
        "json": str(out / "diagnosis.json"),
        "markdown": str(out / "report.md"),
        "html": str(out / "report.html"),
        "plant": str(plant_file),
        "calibrated": str(calibrated),
    }
