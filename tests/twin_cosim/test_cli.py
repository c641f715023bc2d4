"""The twin command line, run as a user would."""

from __future__ import annotations

import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_build_prints_the_fmu_path(tmp_path, twin_cli):
    result = twin_cli("build", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert Path(result.stdout.strip()) == tmp_path / "drive2mass.fmu"


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
