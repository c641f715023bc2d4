"""The twin command line, run as a user would."""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

from fmu_build.build import build_fmu
from twin_cosim.cli import build_parser
from twin_cosim.optimize.algorithms import ALGORITHMS

ROOT = Path(__file__).resolve().parents[2]


def test_build_prints_the_fmu_and_loops_paths(tmp_path, twin_cli):
    """``twin build`` builds the FMU and the loops compiled ahead, and prints both paths."""
    from twin_cosim.loops import ahead

    result = twin_cli("build", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    fmu, library = result.stdout.strip().splitlines()
    assert Path(fmu) == tmp_path / "drive2mass.fmu"
    assert Path(library) == ahead.library_path() and Path(library).is_file()


def test_build_warns_when_the_loops_cannot_be_compiled_ahead(tmp_path, monkeypatch, capsys):
    import argparse

    from twin_cosim.commands import fmu
    from twin_cosim.loops import ahead

    def fail(force: bool = False) -> Path:
        raise ahead.LoopBuildError("compiling the loops ahead failed: Python.h: not found")

    monkeypatch.setattr(ahead, "build", fail)
    args = argparse.Namespace(model="drive2mass", out=str(tmp_path), force=False, fmi=2)
    assert fmu.run_build(args) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == str(tmp_path / "drive2mass.fmu")
    assert "Python.h: not found; the loops will compile just in time" in captured.err


def test_simulate_json_and_files(tmp_path, twin_cli):
    result = twin_cli(
        "simulate", "scenarios/reference1.yaml", "--params", "ga", "--out", str(tmp_path), "--json"
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert set(summary["metrics"]) >= {"E_pk_um", "ITAE", "IAU", "rms_um"}
    assert summary["params"]["Kp_pos"] == 74.8709
    assert 1.0 < summary["metrics"]["E_pk_um"] < 100.0
    for name in ("record.csv", "summary.json", "run.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_simulate_without_plots_writes_the_same_record(tmp_path, twin_cli):
    """--no-plots leaves out run.png only: the record and the metrics are the same."""
    runs = {}
    for name, extra in (("plots", []), ("none", ["--no-plots"])):
        result = twin_cli("simulate", "reference1", "--out", str(tmp_path / name), "--json", *extra)
        assert result.returncode == 0, result.stderr
        runs[name] = json.loads(result.stdout)
    assert runs["none"]["metrics"] == runs["plots"]["metrics"]
    assert runs["none"]["outputs"]["plot"] is None
    assert not (tmp_path / "none" / "run.png").exists()
    assert (tmp_path / "plots" / "run.png").stat().st_size > 0
    record = (tmp_path / "none" / "record.csv").read_bytes()
    assert record == (tmp_path / "plots" / "record.csv").read_bytes()


def test_the_record_csv_is_what_pandas_writes(tmp_path):
    """The fast CSV writer of run records writes the bytes of ``DataFrame.to_csv``, also when
    a forked child formats the second half of a long record, and leaves no temporary file."""
    import numpy as np
    import pandas as pd

    from twin_cosim.commands.console import write_record_csv

    values = np.array(
        [[0.0, -0.0, 1e16, 1e-5, 0.1 + 0.2, np.inf, -np.inf, 5e-324, 9999999999999998.0]] * 3
    )
    values[1] = np.random.default_rng(0).normal(size=values.shape[1]) * 1e-7
    rng = np.random.default_rng(1)
    long = rng.normal(size=(12_001, 4)) * 10.0 ** rng.integers(-60, 20, size=(12_001, 4))
    for name, frame in (
        ("long", pd.DataFrame(long, columns=["t", "x", "error", "current"])),
        ("floats", pd.DataFrame(values, columns=[f"c{i}" for i in range(values.shape[1])])),
        ("nan", pd.DataFrame({"t": [0.0, np.nan], "x": [1.0, 2.5]})),
        ("ints", pd.DataFrame({"t": [0, 1], "x": [1.0, 2.5]})),
    ):
        write_record_csv(tmp_path / f"{name}.csv", frame)
        assert (tmp_path / f"{name}.csv").read_text() == frame.to_csv(index=False), name
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "floats.csv",
        "ints.csv",
        "long.csv",
        "nan.csv",
    ]


def test_bad_scenario_is_a_clear_error(tmp_path, twin_cli):
    bad = tmp_path / "bad.yaml"
    bad.write_text("reference:\n  segments:\n    - dwell: -1\n")
    result = twin_cli("simulate", str(bad), "--out", str(tmp_path))
    assert result.returncode == 2
    assert "bad.yaml: reference.segments[0].dwell: expected a number > 0" in result.stderr
    assert "Traceback" not in result.stderr


def test_optimize_json(tmp_path, twin_cli):
    result = twin_cli(
        "optimize",
        "scenarios/reference1.yaml",
        "--method",
        "cmaes",
        "--budget",
        "12",
        "--workers",
        "1",
        "--quiet",
        "--json",
        "--out",
        str(tmp_path / "c"),
    )
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert set(summary) >= {"best_params", "metrics", "evaluations", "wall_s"}
    assert set(summary["metrics"]) >= {"E_pk_um", "ITAE", "IAU"}
    assert summary["evaluations"] == 12
    assert summary["metrics"]["E_pk_um"] <= summary["reference_metrics"]["E_pk_um"]
    for name in (
        "campaign.json",
        "evaluations.jsonl",
        "progress.json",
        "result.json",
        "convergence.png",
        "best_run.png",
    ):
        assert (tmp_path / "c" / name).stat().st_size > 0


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(commands.choices)


def options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and a.dest != "help"]


def test_every_option_shows_its_default():
    for name, parser in subcommands().items():
        formatter = parser._get_formatter()
        for action in options(parser):
            text = formatter._get_help_string(action) % {"default": action.default}
            assert "default" in text or "required" in text, (name, action.option_strings)


def test_readme_synopsis_lists_every_option():
    """Each `twin X` line of the README's command synopsis names all options of X."""
    readme = (ROOT / "README.md").read_text()
    synopsis = readme.split("## Commands", 1)[1].split("```bash", 1)[1].split("```", 1)[0]
    blocks = re.split(r"\n(?=twin )", synopsis.strip())
    documented = {block.split()[1]: block for block in blocks}
    assert set(documented) == set(subcommands())
    for name, parser in subcommands().items():
        for action in options(parser):
            option = re.escape(action.option_strings[0]) + r"(?![\w-])"
            assert re.search(option, documented[name]), (name, action.option_strings)


def test_diagnose_help_defaults_are_the_settings_defaults():
    from twin_cosim.gap.settings import DiagnosisSettings

    help_text = {a.dest: a.help for a in options(subcommands()["diagnose"])}
    assert f"else {DiagnosisSettings().split})" in help_text["split"]
    assert f"else {DiagnosisSettings().max_effects})" in help_text["max_effects"]


def test_method_choices_are_the_registry():
    (method,) = [a for a in options(subcommands()["optimize"]) if a.dest == "method"]
    assert tuple(method.choices) == tuple(ALGORITHMS)


def test_shipped_scenario_by_name_from_any_folder(tmp_path):
    command = [sys.executable, "-m", "twin_cosim", "simulate", "reference1", "--json"]
    result = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert Path(summary["scenario"]).name == "reference1.yaml"
    assert (tmp_path / "out" / "reference1" / "record.csv").is_file()
    assert summary["warnings"] == []


def test_optimize_a_shipped_scenario_by_name_from_any_folder(tmp_path):
    """The campaign fingerprints the scenario's file, found by name like everywhere else."""
    command = [sys.executable, "-m", "twin_cosim", "optimize", "reference1", "--method", "ce"]
    command += ["--budget", "6", "--workers", "1", "--quiet", "--json", "--out", "c"]
    result = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["evaluations"] == 6


def test_a_plant_of_another_model_is_warned_about(tmp_path, twin_cli):
    emps = build_fmu("emps")
    result = twin_cli(
        "simulate", "reference1", "--plant", str(emps), "--out", str(tmp_path), "--json"
    )
    assert result.returncode == 0, result.stderr
    assert "twin: warning: " in result.stderr
    assert "made for the plant model 'drive2mass'" in result.stderr
    (warning,) = json.loads(result.stdout)["warnings"]
    assert "is model 'emps'" in warning


def test_the_fmi3_fmu_of_the_scenarios_model_runs_as_its_own_plant(tmp_path, twin_cli):
    """`--plant` takes the FMI 3.0 FMU of the same model: no mismatch warning (its independent
    variable ``time`` is no other variable), the record of the FMI 2.0 FMU."""
    fmi3 = build_fmu("drive2mass", fmi_version=3)
    three = twin_cli("simulate", "reference1", "--plant", str(fmi3), "--out", str(tmp_path / "3"))
    two = twin_cli("simulate", "reference1", "--no-plots", "--out", str(tmp_path / "2"))
    assert three.returncode == 0 and two.returncode == 0, three.stderr + two.stderr
    assert "warning" not in three.stderr
    assert (tmp_path / "3" / "record.csv").read_bytes() == (
        tmp_path / "2" / "record.csv"
    ).read_bytes()


def test_a_second_run_of_a_scenario_needs_no_scipy():
    """Reference preparation is cached across runs: resolving reference 1 again (a new
    process) reads the stored grid instead of importing SciPy's spline."""
    code = (
        "import sys\n"
        "from twin_cosim.scenario import resolve_scenario\n"
        "resolve_scenario('reference1')\n"
        "print('scipy' in sys.modules)\n"
    )
    answers = [
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True
        ).stdout.strip()
        for _ in range(2)
    ]
    assert answers[1] == "False"
