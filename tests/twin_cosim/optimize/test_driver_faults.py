"""The campaign driver refuses to mix inputs, to share a folder, or to store arguments it cannot
run."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from scenario_texts import scenario_text

from twin_cosim.cli import main
from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec, load_campaign_spec
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.optimize.store import CampaignError, FolderLock

SHORT = scenario_text(move=0.2, back=False, optimize="abort_error_um: 50.0")


@pytest.fixture()
def scenario(tmp_path) -> Path:
    path = tmp_path / "short.yaml"
    path.write_text(SHORT)
    return path


def run(scenario: Path, out: Path, budget: int = 10, **options) -> object:
    spec = CampaignSpec(str(scenario), "cmaes", seed=1, budget=budget, fmu=options.pop("fmu", None))
    return run_campaign(AxisProblem.resolve(spec), out, workers=1, progress=False, **options)


def test_resume_refuses_an_edited_scenario(scenario, tmp_path):
    run(scenario, tmp_path / "c")
    scenario.write_text(scenario_text(move=0.2, back=False, optimize="abort_error_um: 60.0"))
    spec = load_campaign_spec(tmp_path / "c")
    with pytest.raises(CampaignError, match=r"scenario .*short.yaml.* changed"):
        run_campaign(
            AxisProblem.resolve(spec), tmp_path / "c", workers=1, resume=True, progress=False
        )


def test_resume_refuses_another_plant_fmu(scenario, tmp_path, fmu_path):
    run(scenario, tmp_path / "c")
    other = tmp_path / "other.fmu"
    shutil.copy(fmu_path, other)
    with open(other, "ab") as file:  # same members, another archive: still the same plant
        file.write(b"")
    spec = load_campaign_spec(tmp_path / "c")
    same = CampaignSpec(**{**spec.__dict__, "fmu": str(other)})
    run_campaign(AxisProblem.resolve(same), tmp_path / "c", workers=1, resume=True, progress=False)
    emps = Path(__file__).resolve().parents[3] / "build" / "emps.fmu"
    if not emps.exists():
        from fmu_build.build import build_fmu

        emps = build_fmu("emps")
    changed = CampaignSpec(**{**spec.__dict__, "fmu": str(emps)})
    with pytest.raises(CampaignError, match="plant FMU .*emps.fmu.* changed"):
        run_campaign(
            AxisProblem.resolve(changed), tmp_path / "c", workers=1, resume=True, progress=False
        )


def test_cli_resume_checks_the_given_scenario(scenario, tmp_path, capsys):
    run(scenario, tmp_path / "c")
    other = tmp_path / "other.yaml"
    other.write_text(scenario_text(move=0.3, back=False, optimize="abort_error_um: 50.0"))
    status = main(["optimize", str(other), "--resume", str(tmp_path / "c"), "--quiet"])
    assert status == 2
    assert f"scenario {other}" in capsys.readouterr().err
    # The same content under another path (the file moved) resumes.
    moved = tmp_path / "moved.yaml"
    moved.write_text(SHORT)
    assert main(["optimize", str(moved), "--resume", str(tmp_path / "c"), "--quiet"]) == 0


def test_a_second_writer_is_refused_at_once(scenario, tmp_path):
    out = tmp_path / "c"
    out.mkdir()
    with FolderLock(out), pytest.raises(CampaignError, match=f"in use by process {os.getpid()}"):
        run(scenario, out)
    assert not (out / "campaign.json").exists()
    run(scenario, out)  # released: the folder is free again


def test_a_stale_lock_of_a_dead_process_is_taken_over(scenario, tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    out = tmp_path / "c"
    out.mkdir()
    (out / "campaign.lock").write_text(f"{dead.pid}\n")
    result = run(scenario, out)
    assert result.evaluations == 10
    assert not (out / "campaign.lock").exists()


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--budget", "0", "argument --budget: expected a whole number >= 1"),
        ("--seed", "-1", "argument --seed: expected a whole number >= 0"),
        ("--workers", "-1", "argument --workers: expected a whole number >= 1"),
        ("--workers", "-2", "argument --workers: expected a whole number >= 1"),
        ("--workers", "0", "argument --workers: expected a whole number >= 1"),
    ],
)
def test_bad_options_are_refused_before_anything_is_written(
    scenario, tmp_path, capsys, option, value, expected
):
    out = tmp_path / "c"
    with pytest.raises(SystemExit) as exit_info:
        main(["optimize", str(scenario), "--method", "cmaes", option, value, "--out", str(out)])
    assert exit_info.value.code == 2
    assert expected in capsys.readouterr().err
    assert not out.exists()


def test_a_bad_budget_through_the_api_writes_nothing(scenario, tmp_path):
    with pytest.raises(CampaignError, match="budget: expected a whole number >= 1"):
        run(scenario, tmp_path / "c", budget=0)
    assert not (tmp_path / "c").exists()


def test_an_unreachable_scheduler_writes_nothing(scenario, tmp_path):
    pytest.importorskip("distributed")
    import socket

    with socket.socket() as probe:  # a loopback port with nothing listening
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    from twin_cosim.optimize import evaluators

    spec = CampaignSpec(str(scenario), "cmaes", seed=1, budget=10)
    with pytest.raises(evaluators.SchedulerError, match=f"--scheduler tcp://127.0.0.1:{port}"):
        run_campaign(
            AxisProblem.resolve(spec),
            tmp_path / "c",
            scheduler=f"tcp://127.0.0.1:{port}",
            progress=False,
            scheduler_timeout=2.0,
        )
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("text", ["garbage", "[1, 2]", '{"spec": {}}'])
def test_garbage_campaign_json_is_named(scenario, tmp_path, capsys, text):
    out = tmp_path / "c"
    out.mkdir()
    (out / "campaign.json").write_text(text)
    assert main(["optimize", str(scenario), "--resume", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{out / 'campaign.json'}: not a campaign record" in err


@pytest.mark.parametrize(
    "line",
    ['{"x": [1.0]}', "[1, 2, 3]", b"\xff\xfe\x00garbage\x81"],
    ids=["no-key", "json-array", "random-bytes"],
)
def test_a_corrupt_log_line_is_named(scenario, tmp_path, capsys, line):
    run(scenario, tmp_path / "c")
    log = tmp_path / "c" / "evaluations.jsonl"
    data = line if isinstance(line, bytes) else line.encode()
    log.write_bytes(data + b"\n" + log.read_bytes())
    assert main(["optimize", str(scenario), "--resume", str(tmp_path / "c"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{log}: line 1" in err
    assert "Traceback" not in err


def test_resume_record_holds_fingerprints(scenario, tmp_path):
    run(scenario, tmp_path / "c")
    header = json.loads((tmp_path / "c" / "campaign.json").read_text())
    assert set(header["fingerprints"]) == {"scenario", "plant_fmu", "settings"}
