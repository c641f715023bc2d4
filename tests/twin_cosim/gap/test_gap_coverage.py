"""A diagnosis refuses training or held-out data without the motion it needs."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.gap.context import build_context
from twin_cosim.gap.coverage import missing_regimes
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.synth import synthesize
from twin_cosim.measured import MeasuredDataError, read_measured_csv
from twin_cosim.scenario import load_scenario


def _run(tmp_path: Path, text: str, name: str):
    """A scenario file of ``text`` and a synthetic run of it (no effect, seeded noise)."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    scenario = load_scenario(path)
    run = tmp_path / f"{name}.csv"
    synthesize(scenario, [], seed=3).run.frame().to_csv(run, index=False)
    return scenario, read_measured_csv(run)


def test_a_run_without_a_reversal_is_refused_naming_the_file(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(back=False, repeat=2), "oneway")
    with pytest.raises(MeasuredDataError) as error:
        build_context(scenario, [run], [], None, DiagnosisSettings())
    message = str(error.value)
    assert "oneway.csv (t = 0 to " in message
    assert "training data (time split at t = " in message
    assert "hold no reversal" in message
    assert "motion" not in message.split("hold no")[1].split(";")[0]


def test_a_training_half_that_only_dwells_is_refused(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(dwell=1.5, repeat=1), "dwell")
    with pytest.raises(
        MeasuredDataError,
        match=r"dwell\.csv .*the training data .* hold no "
        r"motion and no reversal",
    ):
        build_context(scenario, [run], [], None, DiagnosisSettings(split=0.3))


def test_held_out_data_are_checked_too(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(dwell=1.5, repeat=1), "late")
    with pytest.raises(MeasuredDataError, match=r"the held-out data .* hold no .*reversal"):
        build_context(scenario, [run], [], None, DiagnosisSettings(split=0.9))


def test_a_run_that_moves_and_reverses_in_both_parts_passes(tmp_path):
    scenario, run = _run(tmp_path, scenario_text(repeat=2), "both")
    context = build_context(scenario, [run], [], None, DiagnosisSettings())
    grids = [scenario.reference]
    assert missing_regimes(context.train, grids) == []
    assert missing_regimes(context.judged, grids) == []
