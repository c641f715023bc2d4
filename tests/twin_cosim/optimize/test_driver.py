"""The campaign driver: evaluators agree, kill -9 and resume loses nothing, Dask, comparison
tables."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.controller_set import TABLE3
from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.comparison import load_comparison, run_comparison
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.store import CampaignError

ROOT = Path(__file__).resolve().parents[3]
SHORT = scenario_text(
    optimize="bounds: {Kp_pos: [20.0, 3000.0]}   # wide enough to hold runaway candidates\n"
    "abort_error_um: 50.0               # ... which the abort band stops early"
)


@pytest.fixture(scope="module")
def short_scenario(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("scenario") / "short.yaml"
    path.write_text(SHORT)
    return str(path)


def campaign(short_scenario, tmp_path, name, workers, method="ce", budget=60, scheduler=None):
    spec = CampaignSpec(short_scenario, method, seed=3, budget=budget)
    return run_campaign(
        AxisProblem.resolve(spec),
        tmp_path / name,
        workers=workers,
        scheduler=scheduler,
        progress=False,
    )


def test_serial_and_pool_give_the_same_campaign(short_scenario, tmp_path):
    serial = campaign(short_scenario, tmp_path, "serial", workers=1)
    pool = campaign(short_scenario, tmp_path, "pool", workers=2)
    assert serial.best_params == pool.best_params
    assert serial.fitness == pool.fitness
    assert serial.evaluations == pool.evaluations == 60
    assert serial.fitness < serial.reference["E_pk_um"]
    assert (tmp_path / "pool" / "progress.json").exists()


def test_the_log_is_synced_once_per_generation(short_scenario, tmp_path, monkeypatch):
    """Every evaluation is flushed as it completes; the disk sync comes once per generation
    (and at the close), not once per evaluation."""
    import twin_cosim.optimize.store as store

    synced = []
    monkeypatch.setattr(store.os, "fsync", lambda fd: synced.append(fd))
    result = campaign(short_scenario, tmp_path, "synced", workers=1, budget=40)
    progress = json.loads((tmp_path / "synced" / "progress.json").read_text())
    lines = (tmp_path / "synced" / "evaluations.jsonl").read_text().splitlines()
    assert len(lines) == result.evaluations == 40
    assert len(synced) == progress["generation"] + 1  # each generation, then the close


def test_a_cmaes_refinement_evaluates_its_start_first(short_scenario, tmp_path):
    """``--start`` with CMA-ES: the start set is the first evaluation, so the campaign's best
    is never worse than the set it refines."""
    spec = CampaignSpec(short_scenario, "cmaes", seed=3, budget=12, start="ga")
    result = run_campaign(AxisProblem.resolve(spec), tmp_path / "refine", workers=1, progress=False)
    first = json.loads((tmp_path / "refine" / "evaluations.jsonl").read_text().splitlines()[0])
    assert first["x"] == pytest.approx(list(TABLE3["ga"].as_array()), rel=1e-12)
    assert result.fitness <= first["fitness"]


def test_a_pool_campaign_leaves_the_plant_to_its_workers(short_scenario, tmp_path):
    """With a process pool the reference runs and the evaluations run in the workers: the
    parent loads neither numba nor fmpy (it prepares while they start)."""
    code = (
        "import sys\n"
        "from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec\n"
        "from twin_cosim.optimize.driver import run_campaign\n"
        f"spec = CampaignSpec({short_scenario!r}, 'ce', seed=3, budget=8)\n"
        "problem = AxisProblem.resolve(spec)\n"
        f"run_campaign(problem, {str(tmp_path / 'c')!r}, workers=2, progress=False)\n"
        "print(sorted({'numba', 'fmpy', 'matplotlib'} & set(sys.modules)))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=False
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


def test_a_campaigns_figures_are_drawn_by_its_painter(short_scenario, tmp_path):
    """``twin optimize`` on a pool writes convergence.png and best_run.png from its painter:
    the command's process never imports matplotlib, pandas nor the plant."""
    out = tmp_path / "c"
    code = (
        "import sys\n"
        "from twin_cosim.cli import main\n"
        f"args = ['optimize', {short_scenario!r}, '--method', 'ce', '--budget', '8',\n"
        f"        '--workers', '2', '--quiet', '--out', {str(out)!r}]\n"
        "code = main(args)\n"
        "print(code, sorted({'numba', 'fmpy', 'matplotlib', 'pandas'} & set(sys.modules)))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "0 []"
    for figure in ("convergence.png", "best_run.png"):
        assert (out / figure).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", figure


def test_a_figure_that_cannot_be_written_is_said_and_fails_the_command(
    short_scenario, tmp_path, twin_cli
):
    out = tmp_path / "c"
    (out / "best_run.png").mkdir(parents=True)  # a folder where the figure goes
    done = twin_cli(
        "optimize", short_scenario, "--method", "ce", "--budget", "8", "--workers", "2",
        "--quiet", "--out", str(out),
    )  # fmt: skip
    assert done.returncode == 1
    assert "the figure was not drawn" in done.stderr and "best_run.png" in done.stderr
    assert (out / "result.json").exists()  # the result is kept
    assert (out / "convergence.png").read_bytes()[:4] == b"\x89PNG"
    assert "best_run.png" not in done.stdout


def test_failing_candidates_do_not_stop_the_campaign(short_scenario, tmp_path):
    result = campaign(short_scenario, tmp_path, "ga", workers=1, method="ga", budget=100)
    entries = [
        json.loads(line)
        for line in (tmp_path / "ga" / "evaluations.jsonl").read_text().splitlines()
    ]
    assert any(e["status"] == "unstable" for e in entries)  # error beyond 50 um: stopped
    assert result.status == "ok"


def test_existing_folder_needs_resume(short_scenario, tmp_path):
    campaign(short_scenario, tmp_path, "once", workers=1, budget=20)
    with pytest.raises(CampaignError, match="already holds a campaign"):
        campaign(short_scenario, tmp_path, "once", workers=1, budget=20)


def test_kill_9_mid_generation_then_resume_loses_nothing(short_scenario, tmp_path, twin_cli):
    reference = campaign(short_scenario, tmp_path, "uninterrupted", workers=1, budget=100)
    out = tmp_path / "killed"
    command = [
        sys.executable,
        "-m",
        "twin_cosim",
        "optimize",
        short_scenario,
        "--method",
        "ce",
        "--seed",
        "3",
        "--budget",
        "100",
        "--workers",
        "1",
        "--quiet",
        "--out",
        str(out),
    ]
    process = subprocess.Popen(
        command, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    log = out / "evaluations.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline and process.poll() is None:
        if log.exists() and len(log.read_text().splitlines()) >= 30:  # inside generation 2
            break
        time.sleep(0.005)
    assert process.poll() is None, process.stderr.read().decode()
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    before = {
        json.loads(line)["key"] for line in log.read_text().splitlines() if line.endswith("}")
    }
    assert 30 <= len(before) < 100
    result = twin_cli("optimize", short_scenario, "--resume", str(out), "--quiet", "--json")
    assert result.returncode == 0, result.stderr
    resumed = json.loads(result.stdout)
    after = [json.loads(line)["key"] for line in log.read_text().splitlines()]
    assert before <= set(after)  # nothing completed before the kill was lost
    assert len(after) == len(set(after))  # nothing evaluated twice
    assert resumed["evaluations_reused"] >= len(before)
    assert resumed["best_params"] == reference.best_params
    assert resumed["evaluations"] == reference.evaluations


def test_resume_refuses_other_options(short_scenario, tmp_path, twin_cli):
    campaign(short_scenario, tmp_path, "done", workers=1, budget=20)
    result = twin_cli("optimize", short_scenario, "--resume", str(tmp_path / "done"), "--seed", "4")
    assert result.returncode == 2
    assert "options differ from the stored campaign" in result.stderr


def test_dask_local_cluster_gives_the_same_campaign(short_scenario, tmp_path):
    distributed = pytest.importorskip("distributed")
    serial = campaign(short_scenario, tmp_path, "serial", workers=1, budget=40)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        on_dask = campaign(
            short_scenario,
            tmp_path,
            "dask",
            workers=None,
            budget=40,
            scheduler=cluster.scheduler_address,
        )
    assert on_dask.best_params == serial.best_params
    assert on_dask.evaluations == serial.evaluations


def test_comparison_writes_tables_3_to_5(short_scenario, tmp_path):
    path = tmp_path / "campaign.yaml"
    path.write_text(
        f"name: small\nscenario: {short_scenario}\nvalidation: {short_scenario}\n"
        "methods: [ce, cmaes]\nseed: 1\nbudgets: {ce: 40, cmaes: 40}\n"
    )
    text = run_comparison(load_comparison(path), tmp_path / "out", workers=1, progress=False)
    for heading in ("Table 3", "Table 4", "Table 5"):
        assert heading in text
    for row in ("| FT |", "| CE |", "| CMA-ES |"):
        assert row in text
    for name in (
        "tables.md",
        "tables.json",
        "convergence.png",
        "errors_optimized.png",
        "errors_validation.png",
    ):
        assert (tmp_path / "out" / name).stat().st_size > 0
    # A second call reuses the finished campaigns.
    assert (
        run_comparison(load_comparison(path), tmp_path / "out", workers=1, progress=False) == text
    )


def test_comparison_file_mistakes_are_named(tmp_path):
    from twin_cosim.scenario import ScenarioError

    path = tmp_path / "c.yaml"
    path.write_text("scenario: s.yaml\nmethods: [ce, pso]\n")
    with pytest.raises(ScenarioError, match="c.yaml: methods: expected a list from"):
        load_comparison(path)
