"""Ctrl-C at random moments of campaigns: each must end with exit 130 within 10 s, leave no
process and keep a folder that resumes.

Runs ``twin optimize`` (fresh, then resumed) and ``twin compare`` on the local pool and, with
``--dask``, on a Dask scheduler and worker started here on 127.0.0.1. Each trial starts a
command in its own process group, waits a random delay, sends SIGINT to the group (what a
terminal's Ctrl-C does; ``--twice`` sends it twice, as ``timeout -s INT`` does: to the command,
then to its group) and checks the end. Prints one line per trial and the tally.

    python benchmarks/interrupts.py --trials 50             # the Goal of issue 18
    python benchmarks/interrupts.py --trials 50 --dask

The delays are drawn from ``--min-delay`` to ``--max-delay`` s (start-up included), seeded.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
END_WITHIN_S = 10.0  # the Goal: exit 130 within 10 s of the Ctrl-C

CAMPAIGN = """name: interrupts
scenario: reference1
validation: reference2
methods: [ga, ce]
seed: 0
budgets: {ga: 300, ce: 200}
"""


def group_alive(pgid: int) -> list[int]:
    """Processes (not zombies) of the process group ``pgid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] != "Z" and int(fields[2]) == pgid:
            found.append(int(stat.parent.name))
    return found


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def start_dask(folder: Path) -> tuple[str, list[subprocess.Popen]]:
    """A Dask scheduler and one worker (2 threads) on 127.0.0.1; their address and processes."""
    address = f"tcp://127.0.0.1:{free_port()}"
    port = address.rsplit(":", 1)[1]
    common = {"cwd": folder, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            port,
            "--no-dashboard",
        ],
        **common,
    )
    time.sleep(3.0)
    worker = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_worker",
            address,
            "--host",
            "127.0.0.1",
            "--nthreads",
            "2",
            "--nworkers",
            "1",
            "--no-dashboard",
        ],
        **common,
    )
    time.sleep(5.0)
    return address, [worker, scheduler]


def resumable(folder: Path) -> bool:
    """Whether the folder's record and log read whole (what ``--resume`` reads)."""
    campaigns = (
        [folder]
        if (folder / "campaign.json").exists()
        else sorted(p.parent for p in folder.glob("*/campaign.json"))
    )
    try:
        for campaign in campaigns:
            json.loads((campaign / "campaign.json").read_text())
            log = campaign / "evaluations.jsonl"
            if log.exists():
                for line in log.read_text().splitlines():
                    json.loads(line)
    except (OSError, ValueError):
        return False
    return True


def trial(command: list[str], delay: float, twice: bool, env: dict[str, str]) -> str:
    """Run ``command``, Ctrl-C it after ``delay`` s; the outcome's name."""
    process = subprocess.Popen(
        command,
        cwd=ROOT,
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(delay)
    if process.poll() is not None:
        return f"ended before the signal ({process.returncode})"
    if twice:
        os.kill(process.pid, signal.SIGINT)
    os.killpg(process.pid, signal.SIGINT)
    sent = time.monotonic()
    try:
        process.wait(timeout=END_WITHIN_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
        return "HUNG (killed)"
    took = time.monotonic() - sent
    deadline = time.monotonic() + 5.0
    while (left := group_alive(process.pid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    stderr = process.stderr.read()
    if left:
        os.killpg(process.pid, signal.SIGKILL)
        return f"processes left {left}"
    if process.returncode != 130:
        return f"exit {process.returncode}: {stderr.strip().splitlines()[-1:]}"
    if "Traceback" in stderr:
        return "traceback"
    return f"ok ({took:.1f} s)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--min-delay", type=float, default=1.0)
    parser.add_argument("--max-delay", type=float, default=12.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--twice", action="store_true", help="SIGINT to the command, then its group"
    )
    parser.add_argument("--dask", action="store_true", help="on a Dask scheduler (127.0.0.1)")
    args = parser.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="interrupts-") as scratch:
        folder = Path(scratch)
        (folder / "campaign.yaml").write_text(CAMPAIGN)
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        cluster: list[subprocess.Popen] = []
        where = ["--workers", "2"]
        if args.dask:
            address, cluster = start_dask(folder)
            where = ["--scheduler", address]
        twin = [sys.executable, "-m", "twin_cosim"]
        resumed = folder / "resumed"

        def optimize(out: Path, budget: str) -> list[str]:
            return [
                *twin,
                "optimize",
                "reference1",
                "--method",
                "ga",
                "--budget",
                budget,
                *where,
                "--quiet",
                "--no-plots",
                "--out",
                str(out),
            ]

        def resume(out: Path) -> list[str]:
            if not (out / "campaign.json").exists():  # the first one starts it
                return optimize(out, "100000")
            return [
                *twin,
                "optimize",
                "reference1",
                "--resume",
                str(out),
                *where,
                "--quiet",
                "--no-plots",
            ]

        kinds = {
            "fresh": lambda i: (optimize(folder / f"fresh{i}", "2000"), folder / f"fresh{i}"),
            "resumed": lambda i: (resume(resumed), resumed),
            "compare": lambda i: (
                [
                    *twin,
                    "compare",
                    str(folder / "campaign.yaml"),
                    *where,
                    "--quiet",
                    "--no-plots",
                    "--out",
                    str(folder / f"compare{i}"),
                ],
                folder / f"compare{i}",
            ),
        }
        tally: Counter[str] = Counter()
        try:
            for i in range(args.trials):
                kind = list(kinds)[i % len(kinds)]
                command, out = kinds[kind](i)
                delay = rng.uniform(args.min_delay, args.max_delay)
                outcome = trial(command, delay, args.twice, env)
                if outcome.startswith("ok") and not resumable(out):
                    outcome = "folder not resumable"
                tally[outcome.split(" (")[0]] += 1
                print(f"{i + 1:3d} {kind:8s} Ctrl-C after {delay:5.2f} s: {outcome}", flush=True)
        finally:
            for process in cluster:
                process.terminate()
                process.wait()
    where_name = "Dask" if args.dask else "local pool of 2"
    print(
        f"tally ({where_name}, {'twice' if args.twice else 'once'}): "
        + ", ".join(f"{name}: {count}" for name, count in tally.most_common())
    )


if __name__ == "__main__":
    main()
