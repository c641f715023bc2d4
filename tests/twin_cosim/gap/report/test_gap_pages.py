"""The report a user reads: stdout, report.md and report.html of ``twin diagnose``.

No Python repr anywhere (dicts, lists, None, True/False, raw JSON), numbers to three
significant digits, every number of the verdict in the table beside it, and the progress bar
at 100 % when the command ends.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from scenario_texts import scenario_text

from twin_cosim import cli
from twin_cosim.gap import settings as diagnosis_settings
from twin_cosim.gap.location import Location
from twin_cosim.gap.report.pages import _axis_sections
from twin_cosim.gap.synth import parse_effect, synthesize
from twin_cosim.gap.verdict import quantity
from twin_cosim.measured import compared_label, position_label
from twin_cosim.scenario import load_scenario
from twin_cosim.scenario.plant_parameters import read_plant_parameters

EXCITATION = scenario_text(
    "report-excitation", speed=0.02, acceleration=0.2, move=1.0, stop=0.2, dwell=0.3, repeat=2
)
# Stribeck friction is found; the backlash change, left out of the hypotheses, is what is left.
HIDDEN = (
    "stribeck:stribeck_friction=0.25,stribeck_speed=0.4",
    "backlash_change:delta_backlash=8e-6",
)
REPRS = [
    r"\{'",  # a dict
    r"\['",  # a list of strings
    r"\bNone\b",
    r"\bTrue\b",
    r"\bFalse\b",
    r"\{\}",
    r'"\w+": ',  # raw JSON
    r"\w=\d",  # key=value of a dict written as is
]
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]\d+)?")


@dataclasses.dataclass(frozen=True)
class Output:
    stdout: str
    stderr: str
    folder: Path


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory) -> Output:
    """``twin diagnose --out DIR`` on a run with two effects, two hypotheses, one accepted."""
    folder = tmp_path_factory.mktemp("report")
    scenario_path = folder / "excitation.yaml"
    scenario_path.write_text(EXCITATION)
    scenario = load_scenario(scenario_path)
    synthesis = synthesize(scenario, [parse_effect(e) for e in HIDDEN], perturb=0.02, seed=4)
    run = folder / "run.csv"
    synthesis.run.frame().to_csv(run, index=False)

    def two_hypotheses(*args, **kwargs):  # the whole library would take minutes
        settings = original(*args, **kwargs)
        return dataclasses.replace(settings, hypotheses=("stribeck", "coulomb_change"))

    original = diagnosis_settings.settings_from
    stdout, stderr = io.StringIO(), io.StringIO()
    argv = ["diagnose", str(scenario_path), "--measured", str(run), "--max-effects", "1"]
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(stdout):
        patch.setattr(diagnosis_settings, "settings_from", two_hypotheses)
        with contextlib.redirect_stderr(stderr):
            status = cli.main([*argv, "--workers", "1", "--out", str(folder / "out")])
    assert status == 0, stderr.getvalue()
    return Output(stdout.getvalue(), stderr.getvalue(), folder / "out")


def _pages(diagnosed: Output) -> dict[str, str]:
    return {
        "stdout": diagnosed.stdout,
        "report.md": (diagnosed.folder / "report.md").read_text(),
        "report.html": (diagnosed.folder / "report.html").read_text(),
    }


def test_no_python_repr_in_any_output_meant_for_people(diagnosed):
    for name, text in _pages(diagnosed).items():
        for pattern in REPRS:
            found = re.search(pattern, text)
            around = text[max(found.start() - 80, 0) : found.end() + 80] if found else ""
            assert not found, f"{name}: {pattern} in ...{around}..."


def _table_after(markdown: str, heading_start: str) -> list[list[str]]:
    """The Markdown table under the first heading that starts so."""
    lines = markdown.split("\n## " + heading_start, 1)[1].split("\n## ", 1)[0].splitlines()
    rows = [line for line in lines if line.startswith("| ")]
    return [[c.strip() for c in row.strip("|").split("|")] for row in rows]


def _significant_digits(token: str) -> int:
    mantissa = token.lstrip("-").split("e")[0]
    digits = mantissa.replace(".", "").lstrip("0")
    return len(digits.rstrip("0")) if "." not in mantissa else len(digits)


def test_numbers_have_three_significant_digits(diagnosed):
    markdown = (diagnosed.folder / "report.md").read_text()
    tables = [line for line in markdown.splitlines() if line.startswith("| ") and "/" not in line]
    for line in tables + diagnosed.stdout.splitlines()[:-1]:
        for token in NUMBER.findall(line):
            assert _significant_digits(token) <= 3, f"{token} in {line}"


def test_every_number_of_the_verdict_is_in_the_table_beside_it(diagnosed):
    markdown = (diagnosed.folder / "report.md").read_text()
    verdict = markdown.split("## Verdict\n\n", 1)[1].split("\n", 1)[0]
    assert "explained in part: stribeck" in verdict and "located at" in verdict
    table = _table_after(markdown, "The verdict's figures")
    assert table[0][1:] == ["before the accepted effects", "after the accepted effects"]
    cells = {n for row in table[1:] for cell in row for n in NUMBER.findall(cell)}
    assert set(NUMBER.findall(verdict)) <= cells, set(NUMBER.findall(verdict)) - cells
    assert "(the two add in quadrature)" in verdict
    assert verdict.startswith(diagnosed.stdout.splitlines()[0])


def test_the_verdicts_spans_are_the_after_span_table(diagnosed):
    markdown = (diagnosed.folder / "report.md").read_text()
    verdict = markdown.split("## Verdict\n\n", 1)[1].split("\n", 1)[0]
    spans = _table_after(markdown, "After the accepted effects (held-out data): spans")
    named = re.findall(r"(-?[\d.]+)-([\d.]+) mm", verdict)
    assert named, verdict
    assert set(named) <= {(row[0], row[1]) for row in spans[1:]}


def test_the_model_error_is_in_the_json_the_report_and_plant_yaml_alike(diagnosed):
    """What the calibrated twin still misses on the held-out runs: the same three figures in
    diagnosis.json and plant.yaml, and in the report with their units."""
    found = json.loads((diagnosed.folder / "diagnosis.json").read_text())["gap"]["model_error"]
    written = read_plant_parameters(diagnosed.folder / "plant.yaml").model_error
    assert found == written.as_dict()
    markdown = (diagnosed.folder / "report.md").read_text()
    section = markdown.split("## What the calibrated twin still misses", 1)[1].split("\n## ")[0]
    assert f"largest {quantity(written.position_peak_m, 'm')}" in section
    words, unit = compared_label("current")
    assert f"{words}: RMS {quantity(written.current_rms_A, unit)}" in section


def test_the_progress_bar_ends_at_100_percent(diagnosed):
    bars = [b for b in re.split(r"[\r\n]", diagnosed.stderr) if b.startswith("diagnose:")]
    assert bars and "100%" in bars[-1], bars[-1:]


def test_a_look_alike_group_is_explained():
    """Why the braces: both passed, their reductions are close, their predicted changes
    correlate; and which fit the calibrated plant holds."""
    import types

    import numpy as np

    from twin_cosim.gap.report.pages import lookalikes
    from twin_cosim.gap.settings import DiagnosisSettings

    change = np.sin(np.linspace(0, 20, 400))

    def candidate(name, reduction, noise, values):
        judgement = types.SimpleNamespace(reduction=reduction, change=change + noise)
        fit = types.SimpleNamespace(values=values)
        return types.SimpleNamespace(name=name, judgement=judgement, fit=fit)

    noise = 0.05 * np.cos(np.linspace(0, 57, 400))
    step = types.SimpleNamespace(
        index=2,
        pair=None,
        accepted=["current_lag", "dead_time"],
        candidates=[
            candidate("current_lag", 0.541, 0.0, {"current_time_constant": 3.02e-4}),
            candidate("dead_time", 0.502, noise, {"dead_time_steps": 5.0}),
        ],
    )
    d = types.SimpleNamespace(
        settings=DiagnosisSettings(),
        steps=[step],
        context=types.SimpleNamespace(model="drive2mass"),
    )
    text = lookalikes(d)
    assert text.startswith("{current_lag, dead_time}: in round 2 each passed every held-out test")
    assert "(54.1 % and 50.2 %) differ by less than 10 percentage points" in text
    assert "correlate with the first's at 0.999 (at least 0.9)" in text
    assert "holds the fit of its first, current_lag (current_time_constant 302 us)" in text


def test_a_rotor_is_placed_by_regime_and_order_and_a_carriage_by_spans():
    """An open-loop rotor turns without travel: one section says why no span of an axis is
    named; a carriage with nothing concentrated gets both span sections, each saying so."""

    def diagnosis(compared: str) -> SimpleNamespace:
        empty = Location({}, {}, [], {})
        return SimpleNamespace(
            context=SimpleNamespace(position_label=position_label(compared, 1e-3)),
            where=empty,
            remaining_where=empty,
        )

    ((title, text),) = _axis_sections(diagnosis("motor_speed"))
    assert title == "Along the axis" and "turns without travel" in text
    before, after = _axis_sections(diagnosis("current"))
    assert before[0].startswith("Before") and "no span stands out" in before[1]
    assert after[0].startswith("After") and "no span stands out" in after[1]
