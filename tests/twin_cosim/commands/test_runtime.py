"""``twin watch`` as a user runs it, against a server of the model on loopback: a drift alarmed,
named and diagnosed, the log, plot and report; faults (bad windows, the server going away and
back, windows too fast for the client); SIGINT and SIGTERM; a server that refuses the client."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "runtime"))
from runtime_cases import ServerThread, cycle, cycle_file, free_port, machine  # noqa: E402

from twin_cosim.runtime.opcua import SERVER_URI, Security, self_signed  # noqa: E402
from twin_cosim.runtime.virtual_machine import Drift  # noqa: E402
from twin_cosim.runtime.watch_log import read_log  # noqa: E402

ROOT = Path(__file__).resolve().parents[3]


def start_watch(scenario: Path, endpoint: str, out: Path, *options: str) -> subprocess.Popen:
    command = [
        sys.executable,
        "-m",
        "twin_cosim",
        "watch",
        str(scenario),
        "--endpoint",
        endpoint,
        "--out",
        str(out),
        "--poll",
        "0.2",
        "--reconnect-timeout",
        "20",
        *options,
    ]
    return subprocess.Popen(
        command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def log_lines(out: Path) -> list[dict]:
    path = out / "windows.jsonl"
    return read_log(path) if path.exists() else []


def wait_for(out: Path, condition, timeout: float = 120.0) -> list[dict]:
    """The log once ``condition(lines)`` holds (bounded in time)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        lines = log_lines(out)
        if condition(lines):
            return lines
        time.sleep(0.1)
    raise AssertionError(f"timed out; log: {log_lines(out)[-3:]}")


def page_state(port: int, condition, timeout: float = 20.0) -> dict:
    """The live page's state once ``condition(state)`` holds (bounded in time)."""
    deadline = time.monotonic() + timeout
    while True:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/state.json", timeout=10) as answer:
            state = json.load(answer)
        if condition(state) or time.monotonic() > deadline:
            return state
        time.sleep(0.1)


def checked(sequence: int):
    return lambda lines: any(
        line.get("sequence") == sequence and ("window" in line) for line in lines
    )


def test_a_drift_is_alarmed_named_diagnosed_and_written_where_it_belongs(tmp_path) -> None:
    scenario = cycle(tmp_path)
    vm = machine(scenario, [Drift("coulomb_change", "delta_coulomb", 0.02)], start=5)
    server = ServerThread(free_port())
    out = tmp_path / "watch"
    page = free_port()
    watch = start_watch(
        cycle_file(tmp_path),
        server.server.endpoint,
        out,
        *("--baseline", "4", "--windows", "8", "--dashboard", str(page)),
    )
    try:
        wait_for(out, lambda lines: any(line.get("event") == "connected" for line in lines))
        for w in range(8):
            sequence = server.publish(vm.window(w).arrays())
            wait_for(out, checked(sequence))
            if w == 6:  # the live page follows the windows
                state = page_state(page, lambda s: len(s["windows"]) == 7 and s["alarms"])
        stdout, stderr = watch.communicate(timeout=180)
        alarms = server.twin_value("Alarms")
        alarm_text = server.twin_value("Alarm")
    finally:
        watch.kill()
        server.close()
    assert watch.returncode == 1, stderr
    lines = read_log(out / "windows.jsonl")
    windows = [line for line in lines if "event" not in line]
    assert [w["window"] for w in windows] == list(range(8))
    assert all(w["real_time_factor"] > 0 for w in windows)
    alarm = next(line for line in lines if line.get("event") == "alarm")
    assert alarm["effect"] == "coulomb_change" and 5 <= alarm["window"] <= 6
    assert alarm["rate_per_window"] == pytest.approx(0.02, rel=0.15)
    assert "drift alarm at window" in stderr and "coulomb_change" in stderr
    diagnosis = next(line for line in lines if line.get("event") == "diagnosis")
    assert diagnosis["effect"] == "coulomb_change", diagnosis
    assert diagnosis["gap_after"] < diagnosis["gap_before"]
    assert lines[-1]["event"] == "end" and lines[-1]["checked"] == 8
    assert (out / "trend.png").stat().st_size > 10_000
    assert "coulomb_change drifts" in (out / "report.md").read_text()
    assert alarms == 1 and json.loads(alarm_text)["effect"] == "coulomb_change"
    assert [w["window"] for w in state["windows"]] == list(range(7))
    assert state["alarms"] and state["alarms"][0]["effect"] == "coulomb_change"
    assert len(state["last"]["twin_position"]) == len(state["last"]["position"]) > 100


def test_bad_windows_are_skipped_and_a_server_that_goes_and_comes_back_is_followed(
    tmp_path,
) -> None:
    scenario = cycle(tmp_path)
    vm = machine(scenario)
    server = ServerThread(free_port(), with_motor_speed=False)
    out = tmp_path / "watch"
    watch = start_watch(cycle_file(tmp_path), server.server.endpoint, out, "--baseline", "3")
    try:
        wait_for(out, lambda lines: any(line.get("event") == "connected" for line in lines))
        good = vm.window(0).arrays()
        nan = dict(good, current=np.where(np.arange(len(good["current"])) == 17, np.nan, 1.0))
        short = dict(good, position=good["position"][:-5])
        for arrays in (good, nan, short):
            sequence = server.publish(arrays)
            wait_for(out, lambda lines, s=sequence: any(x.get("sequence") == s for x in lines))
        server.restart()  # the server goes away and comes back on the same port
        wait_for(out, lambda lines: any(line.get("event") == "restored" for line in lines))
        # Windows faster than the client reads: it misses some and says so.
        server.publish_burst([vm.window(w).arrays() for w in (1, 2, 3)])
        wait_for(out, lambda lines: any(line.get("event") == "missed" for line in lines))
        watch.send_signal(signal.SIGINT)
        _, stderr = watch.communicate(timeout=30)
    finally:
        watch.kill()
        server.close()
    assert watch.returncode == 130
    lines = read_log(out / "windows.jsonl")
    skipped = [line for line in lines if line.get("event") == "skipped"]
    assert [s["window"] for s in skipped] == [1, 2]
    assert "current holds 1 NaN" in skipped[0]["reason"] and "unequal" in skipped[1]["reason"]
    assert "skipped window 1 (Sequence 2)" in stderr
    kinds = [line.get("event") for line in lines]
    assert "lost" in kinds and "restored" in kinds
    sequences = [line["sequence"] for line in lines if "sequence" in line]
    assert len(sequences) == len(set(sequences))  # no window read twice
    missed = sum(line["count"] for line in lines if line.get("event") == "missed")
    assert missed >= 1 and lines[-1]["event"] == "end" and lines[-1]["missed"] == missed
    assert lines[-1]["reason"] == "signal 2"


def test_sigterm_ends_the_watch_with_143_and_a_complete_log(tmp_path) -> None:
    server = ServerThread(free_port())
    out = tmp_path / "watch"
    watch = start_watch(cycle_file(tmp_path), server.server.endpoint, out, "--no-plots")
    try:
        wait_for(out, lambda lines: any(line.get("event") == "connected" for line in lines))
        os.kill(watch.pid, signal.SIGTERM)
        watch.communicate(timeout=30)
    finally:
        watch.kill()
        server.close()
    assert watch.returncode == 143
    lines = read_log(out / "windows.jsonl")
    assert lines[-1]["event"] == "end" and lines[-1]["reason"] == "signal 15"
    assert (out / "report.md").exists() and not (out / "trend.png").exists()


def test_a_server_that_demands_security_refuses_a_plain_client_with_exit_2(tmp_path) -> None:
    certificate, key = self_signed(tmp_path / "pki", "server", SERVER_URI, server=True)
    server = ServerThread(free_port(), Security("SignAndEncrypt", certificate, key, "op", "pw"))
    try:
        watch = start_watch(cycle_file(tmp_path), server.server.endpoint, tmp_path / "w")
        _, stderr = watch.communicate(timeout=60)
    finally:
        server.close()
    assert watch.returncode == 2
    assert "refused the connection" in stderr and "--security" in stderr
    assert "Traceback" not in stderr


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (["--endpoint", "http://127.0.0.1:1"], "expected opc.tcp://HOST:PORT"),
        (["--endpoint", "opc.tcp://127.0.0.1:1", "--security", "Sign"], "needs --certificate"),
        (["--endpoint", "opc.tcp://127.0.0.1:1", "--track", "wear"], "--track wear"),
    ],
)
def test_bad_options_are_one_clear_line_and_exit_2(twin_cli, tmp_path, options, expected):
    result = twin_cli("watch", str(cycle_file(tmp_path)), "--out", str(tmp_path / "w"), *options)
    assert result.returncode == 2 and expected in result.stderr
    assert "Traceback" not in result.stderr
