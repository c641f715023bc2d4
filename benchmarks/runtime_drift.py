"""The runtime twin's goal, measured: ``twin serve`` publishes reference1's cycle (9.7 s of
motion a window) faster than real time on 127.0.0.1 and ``twin watch`` watches it.

Three cases, each a pair of processes (the server, the watch) on loopback:

- ``stationary``: 100 windows of a machine with 2 % calibration error and noise, no drift; the
  goal: no alarm.
- ``friction``: the Coulomb friction level rising by 0.5 % of its value (0.625 N.m) per window
  from window 10 on; the goal: alarmed within 15 windows of its start, named ``coulomb_change``.
- ``backlash``: the backlash growing by 0.2 um per window from window 10 on; the goal: alarmed
  within 15 windows, named ``backlash_change``.

Windows are counted as the server numbers them (Sequence - 1), so a window the watch missed
while starting does not shift the count. For each case the script prints the alarm (window,
windows since the drift's first window, effect), the false alarms, the windows missed, the
real-time factor of the checks (replay, gap and update of one window against its duration:
median and worst), and the full diagnosis (effect, held-out gap before and after, seconds),
and writes the watch's folder (log, trend plot, report) under ``--out``.

    nice -n 10 python benchmarks/runtime_drift.py [--case stationary|friction|backlash|all]
                                                  [--speed 3] [--out out/bench-runtime]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DRIFT_START = 10
CASES = {  # case: (windows, drift arguments of twin serve, the effect that must be named)
    "stationary": (100, [], None),
    "friction": (32, ["--drift", "coulomb_change:delta_coulomb=0.003125"], "coulomb_change"),
    "backlash": (32, ["--drift", "backlash_change:delta_backlash=2e-7"], "backlash_change"),
}


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def twin(*arguments: str, log: Path) -> subprocess.Popen:
    """A ``twin`` command in the background, its output into ``log``."""
    command = [sys.executable, "-m", "twin_cosim", *arguments]
    return subprocess.Popen(
        command, cwd=ROOT, stdout=log.open("w"), stderr=subprocess.STDOUT, text=True
    )


def read_log(path: Path) -> list[dict]:
    """The watch's JSONL log."""
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def run_case(case: str, speed: float, out: Path, seed: int) -> dict:
    """Serve and watch one case; its figures."""
    windows, drift, expected = CASES[case]
    folder = out / case
    folder.mkdir(parents=True, exist_ok=True)
    port = free_port()
    endpoint = f"opc.tcp://127.0.0.1:{port}"
    watch = twin(
        "watch", "reference1", "--endpoint", endpoint, "--out", str(folder), "--quiet",
        "--reconnect-timeout", "120", "--poll", "0.5",
        log=folder / "watch.txt",
    )  # fmt: skip
    time.sleep(10.0)  # the watch loads the plant, then connects once the server listens
    serve = twin(
        "serve", "reference1", "--port", str(port), "--windows", str(windows),
        "--speed", str(speed), "--seed", str(seed), "--drift-start", str(DRIFT_START),
        "--linger", "60", "--quiet", *drift,
        log=folder / "serve.txt",
    )  # fmt: skip
    started = time.monotonic()
    log_path = folder / "windows.jsonl"
    deadline = started + windows * 9.7 / speed + 240.0
    try:
        while time.monotonic() < deadline:
            lines = read_log(log_path) if log_path.exists() else []
            seen = max((x["sequence"] for x in lines if "real_time_factor" in x), default=0)
            alarms = [x for x in lines if x.get("event") == "alarm"]
            diagnosed = {x.get("alarm") for x in lines if x.get("event") == "diagnosis"}
            if seen >= windows and all(a["alarm"] in diagnosed for a in alarms):
                break
            time.sleep(1.0)
        watch.send_signal(signal.SIGINT)
        watch.wait(60)
    finally:
        for process in (watch, serve):
            if process.poll() is None:
                process.kill()
    lines = read_log(log_path)
    checked = [x for x in lines if "real_time_factor" in x]
    sequence_of = {x["window"]: x["sequence"] for x in checked}
    alarms = [x for x in lines if x.get("event") == "alarm"]
    diagnoses = [x for x in lines if x.get("event") == "diagnosis"]
    factors = sorted(x["real_time_factor"] for x in checked if x["phase"] != "baseline")
    figures: dict = {
        "case": case,
        "windows_published": windows,
        "checked": len(checked),
        "missed": sum(x["count"] for x in lines if x.get("event") == "missed"),
        "rtf_median": factors[len(factors) // 2] if factors else None,
        "rtf_worst": factors[0] if factors else None,
        "check_s_median": sorted(x["check_s"] for x in checked)[len(checked) // 2],
        "alarms": [],
        "diagnoses": [],
    }
    for alarm in alarms:
        server_window = sequence_of.get(alarm["window"], alarm["sequence"]) - 1
        figures["alarms"].append(
            {
                "server_window": server_window,
                "windows_after_start": server_window - DRIFT_START + 1 if expected else None,
                "effect": alarm["effect"],
                "rate_per_window": alarm["rate_per_window"],
                "unit": alarm["unit"],
            }
        )
    for found in diagnoses:
        figures["diagnoses"].append(
            {
                key: found.get(key)
                for key in (
                    "effect",
                    "gap_before",
                    "gap_after",
                    "seconds",
                    "idle_wall_s",
                    "wall_s",
                    "failed",
                )
            }
        )
    first = figures["alarms"][0] if figures["alarms"] else None
    if expected is None:
        figures["goal_met"] = not alarms
    else:
        figures["goal_met"] = (
            first is not None
            and first["effect"] == expected
            and 1 <= first["windows_after_start"] <= 15
        )
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=[*CASES, "all"], default="all")
    parser.add_argument("--speed", type=float, default=3.0, help="windows faster than real time")
    parser.add_argument("--seed", type=int, default=1, help="the virtual machine's draw")
    parser.add_argument("--out", default="out/bench-runtime")
    args = parser.parse_args()
    cases = list(CASES) if args.case == "all" else [args.case]
    load = os.getloadavg()
    print(f"load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}, {os.cpu_count()} cores")
    for case in cases:
        figures = run_case(case, args.speed, Path(args.out), args.seed)
        print(json.dumps(figures, indent=1), flush=True)
    load = os.getloadavg()
    print(f"load average at the end {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}")


if __name__ == "__main__":
    main()
