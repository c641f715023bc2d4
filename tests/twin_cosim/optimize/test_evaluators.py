"""Dask: any worker layout gives the serial campaign; scheduler faults are clear, bounded errors.

Every scheduler here listens on 127.0.0.1 only.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.evaluators import SchedulerError
from twin_cosim.optimize.store import CampaignError
from twin_cosim.scenario import load_scenario

distributed = pytest.importorskip("distributed")

SHORT = scenario_text(move=0.2, back=False)


@pytest.fixture(scope="module")
def scenario(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("scenario") / "short.yaml"
    path.write_text(SHORT)
    return str(path)


def local_cluster(workers: int, threads: int):
    return distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=threads,
        processes=False,
        protocol="tcp",
        host="127.0.0.1",
        dashboard_address=None,
    )


def statuses(out: Path) -> list[tuple[str, str, float]]:
    lines = (out / "evaluations.jsonl").read_text().splitlines()
    return sorted((e["key"], e["status"], e["fitness"]) for e in map(json.loads, lines))


def test_a_multi_thread_worker_gives_the_serial_campaign(scenario, tmp_path):
    spec = CampaignSpec(scenario, "ce", seed=2, budget=40)
    serial = run_campaign(AxisProblem.resolve(spec), tmp_path / "serial", workers=1, progress=False)
    with local_cluster(1, 3) as cluster:
        threaded = run_campaign(
            AxisProblem.resolve(spec),
            tmp_path / "dask",
            scheduler=cluster.scheduler_address,
            progress=False,
        )
    assert statuses(tmp_path / "dask") == statuses(tmp_path / "serial")
    assert threaded.best_params == serial.best_params


def test_nothing_listening_fails_fast_naming_the_option():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    from twin_cosim.optimize.evaluators import connect

    start = time.monotonic()
    with pytest.raises(SchedulerError, match=f"--scheduler tcp://127.0.0.1:{port}: no Dask"):
        connect(f"tcp://127.0.0.1:{port}", timeout=1.0)
    assert time.monotonic() - start < 20


def test_a_scheduler_without_workers_says_so(scenario, tmp_path):
    with local_cluster(0, 1) as cluster:
        spec = CampaignSpec(scenario, "ce", seed=2, budget=40)
        with pytest.raises(SchedulerError, match="the scheduler has no worker"):
            run_campaign(
                AxisProblem.resolve(spec),
                tmp_path / "c",
                scheduler=cluster.scheduler_address,
                progress=False,
                scheduler_timeout=1.0,
            )
    assert not (tmp_path / "c").exists()


def test_a_scheduler_lost_mid_run_is_an_error_and_the_log_resumes(scenario, tmp_path):
    spec = CampaignSpec(scenario, "ce", seed=2, budget=80)
    out = tmp_path / "c"
    cluster = local_cluster(1, 1)
    log = out / "evaluations.jsonl"

    def stop_when_started() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if log.exists() and len(log.read_text().splitlines()) >= 5:
                break
            time.sleep(0.02)
        cluster.sync(cluster.scheduler.close)  # the scheduler dies; the worker is left alone

    stopper = threading.Thread(target=stop_when_started, daemon=True)
    stopper.start()
    try:
        with pytest.raises(CampaignError, match="lost the scheduler mid-run.*--resume"):
            run_campaign(
                AxisProblem.resolve(spec),
                out,
                scheduler=cluster.scheduler_address,
                progress=False,
                scheduler_timeout=5.0,
            )
    finally:
        stopper.join(timeout=60)
        cluster.close()
    before = statuses(out)
    resumed = run_campaign(AxisProblem.resolve(spec), out, workers=1, resume=True, progress=False)
    uninterrupted = run_campaign(
        AxisProblem.resolve(spec), tmp_path / "u", workers=1, progress=False
    )
    assert resumed.best_params == uninterrupted.best_params
    assert set(before) <= set(statuses(out))


LONG = """
name: long
reference:
  segments:
    - ramp: {velocity: 0.005, acceleration: 0.05, duration: 60.0}
    - ramp: {velocity: 0.0, acceleration: 0.05, duration: 0.1}
"""


def test_teardown_waits_for_the_running_task(tmp_path):
    from twin_cosim.optimize.axis_problem import ObjectiveSpec
    from twin_cosim.optimize.evaluators import objective_plugin

    path = tmp_path / "long.yaml"
    path.write_text(LONG)
    plugin = objective_plugin(ObjectiveSpec((load_scenario(path),), None, None))
    plugin.setup(worker=None)
    results = []
    fine_tune = [66.667, 0.5, 0.01, 1.0, 0.01, 0.1]
    task = threading.Thread(target=lambda: results.append(plugin.evaluate(fine_tune)))
    task.start()
    deadline = time.monotonic() + 60
    while not plugin._built and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.05)  # the run (about a second) is under way
    plugin.teardown(worker=None)  # what a closing Dask worker does
    task.join(timeout=60)
    assert results and results[0]["status"] == "ok", results
    with pytest.raises(distributed.Reschedule):
        plugin.evaluate(fine_tune)
