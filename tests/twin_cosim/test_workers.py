"""Worker pools leave nothing behind: no process, no extracted FMU, after any kind of end.

Ctrl-C and SIGTERM are raised where they are safe: after a deferred block, never lost.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import random
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import scenario_text

from twin_cosim.optimize.axis_problem import ObjectiveSpec
from twin_cosim.scenario import load_scenario
from twin_cosim.workers import (
    ProcessPool,
    command_temp_folder,
    deferred_signals,
    make_pool,
    stop_handlers,
    tasks_to_give,
    wait_interruptibly,
)

ROOT = Path(__file__).resolve().parents[2]
SHORT = scenario_text(back=False)
FINE_TUNE = np.array([66.667, 0.5, 0.01, 1.0, 0.01, 0.1])

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


def live_in_group(pgid: int) -> list[int]:
    """Processes (not zombies) whose process group is ``pgid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] != "Z" and int(fields[2]) == pgid:
            found.append(int(stat.parent.name))
    return found


def wait_until_gone(pgid: int, seconds: float) -> list[int]:
    deadline = time.monotonic() + seconds
    while (alive := live_in_group(pgid)) and time.monotonic() < deadline:
        time.sleep(0.1)
    return alive


@pytest.fixture()
def private_tmp(tmp_path, monkeypatch) -> Path:
    """A temp folder for this process and the processes it starts."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setenv("TMPDIR", str(folder))
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


@pytest.fixture(scope="module")
def short_scenario(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("scenario") / "short.yaml"
    path.write_text(SHORT)
    return str(path)


def test_pool_removes_every_extracted_fmu(short_scenario, private_tmp):
    pool = make_pool(ObjectiveSpec((load_scenario(short_scenario),), None, None), 2)
    try:
        results = list(pool.imap([FINE_TUNE, FINE_TUNE]))
    finally:
        pool.close()
    assert [r["status"] for _, r in results] == ["ok", "ok"]
    assert list(private_tmp.iterdir()) == []


def test_serial_pool_removes_its_extracted_fmu(short_scenario, private_tmp):
    pool = make_pool(ObjectiveSpec((load_scenario(short_scenario),), None, None), 1)
    pool.close()
    assert list(private_tmp.iterdir()) == []


@pytest.mark.parametrize("workers", [0, -2])
def test_pool_refuses_a_worker_count_below_one(workers):
    with pytest.raises(ValueError, match="workers: expected a whole number >= 1"):
        ProcessPool(ObjectiveSpec("unused.yaml", None, None), workers)


class PidWorker:
    """A worker that answers every task with its process id."""

    def __call__(self, task: object) -> int:
        return os.getpid()

    def close(self) -> None:
        pass


class SlowToStart:
    """A worker factory that, unpickled in a starting worker (before the pool's initializer),
    writes the process id to ``folder/pid`` and waits until ``folder/sent`` exists."""

    def __init__(self, folder: str) -> None:
        self.folder = folder

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        folder = Path(self.folder)
        (folder / "pid.partial").write_text(str(os.getpid()))
        (folder / "pid.partial").replace(folder / "pid")
        deadline = time.monotonic() + 30.0
        while not (folder / "sent").exists() and time.monotonic() < deadline:
            time.sleep(0.02)

    def build(self) -> PidWorker:
        return PidWorker()


def test_a_worker_ignores_ctrl_c_while_it_starts(tmp_path, private_tmp, capfd):
    def interrupt_the_starting_worker() -> None:
        deadline = time.monotonic() + 30.0
        while not (tmp_path / "pid").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        os.kill(int((tmp_path / "pid").read_text()), signal.SIGINT)
        time.sleep(0.2)  # the signal is delivered while the worker still starts
        (tmp_path / "sent").touch()

    pool = ProcessPool(SlowToStart(str(tmp_path)), 1)
    sender = threading.Thread(target=interrupt_the_starting_worker)
    sender.start()
    try:
        results = list(pool.imap(["task"]))
    finally:
        sender.join()
        pool.close()
    assert results == [(0, int((tmp_path / "pid").read_text()))]
    assert "KeyboardInterrupt" not in capfd.readouterr().err


class Tagged:
    """A worker factory whose workers answer (tag, task, process id)."""

    def __init__(self, tag: str) -> None:
        self.tag = tag

    def build(self) -> TaggedWorker:
        return TaggedWorker(self.tag)


class TaggedWorker:
    def __init__(self, tag: str) -> None:
        self.tag = tag

    def __call__(self, task: int) -> tuple[str, int, int]:
        return self.tag, task, os.getpid()

    def close(self) -> None:
        pass


@pytest.mark.parametrize("workers", [1, 2])
def test_one_pool_serves_several_factories_in_turn(private_tmp, workers):
    """Each imap runs on the workers of its factory; without one, on the last factory's; the
    same processes serve them all."""
    with make_pool(None, workers) as pool:
        first = sorted(result for _, result in pool.imap([1, 2, 3, 4], Tagged("a")))
        second = sorted(result for _, result in pool.imap([5, 6], Tagged("b")))
        again = sorted(result for _, result in pool.imap([7]))
    assert [(tag, task) for tag, task, _ in first] == [("a", 1), ("a", 2), ("a", 3), ("a", 4)]
    assert [(tag, task) for tag, task, _ in second + again] == [("b", 5), ("b", 6), ("b", 7)]
    assert {pid for *_, pid in second + again} <= {pid for *_, pid in first}
    assert list(private_tmp.iterdir()) == []


def test_tasks_started_ahead_run_while_the_parent_works_then_the_pool_goes_on(private_tmp):
    """A process pool gives started tasks out at once (on their factory's workers), their
    results taken later; the next imap runs on its own factory; a serial pool starts nothing."""
    with make_pool(None, 2) as pool:
        started = pool.start([1, 2, 3], Tagged("ahead"))
        later = sorted(result for _, result in pool.imap([4, 5], Tagged("b")))
        ahead = sorted(result for _, result in started.results())
        cancelled = pool.start(list(range(50)), Tagged("c"))
        cancelled.cancel()
    assert [(tag, task) for tag, task, _ in ahead] == [("ahead", 1), ("ahead", 2), ("ahead", 3)]
    assert [(tag, task) for tag, task, _ in later] == [("b", 4), ("b", 5)]
    assert sum(f.cancelled() for f in cancelled.futures) > 0  # not all had begun
    assert list(private_tmp.iterdir()) == []
    with make_pool(Tagged("a"), 1) as serial:
        assert serial.start([1], Tagged("ahead")) is None


def test_a_replay_worker_starts_without_scipy():
    """SciPy is imported where a fit runs: a worker that only replays never loads it."""
    code = (
        "import sys\n"
        "from twin_cosim.workers import prepare_replay_worker\n"
        "prepare_replay_worker()\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy'))\n"
    )
    found = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert found.stdout.strip() == "[]"


def test_tasks_are_given_until_in_flight_are_out():
    pending = enumerate("abcde")
    assert list(tasks_to_give(pending, 1, 3)) == [(0, "a"), (1, "b")]
    assert list(tasks_to_give(pending, 3, 3)) == []
    assert list(tasks_to_give(pending, 0, None)) == [(2, "c"), (3, "d"), (4, "e")]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_task_is_made_only_when_a_worker_takes_it(private_tmp, workers):
    """With ``in_flight`` the generator of tasks runs only as results are consumed: each task is
    made with fewer than ``in_flight`` tasks out, and may use every result consumed before."""
    consumed: list[int] = []
    made_after: list[int] = []

    def tasks():
        for task in range(8):
            made_after.append(len(consumed))
            yield task

    with make_pool(Tagged("a"), workers) as pool:
        for _, (_, task, _) in pool.imap(tasks(), in_flight=2):
            consumed.append(task)
    assert sorted(consumed) == list(range(8))
    first_out = min(workers, 2)  # a serial pool takes one task at a time
    assert made_after[:first_out] == [0] * first_out
    assert all(0 <= k - n < 2 for k, n in enumerate(made_after))


class BlasThreadsWorker:
    """A worker that answers the BLAS thread counts its process was started with."""

    def __call__(self, task: object) -> tuple[str | None, str | None]:
        return os.environ.get("OPENBLAS_NUM_THREADS"), os.environ.get("OMP_NUM_THREADS")

    def close(self) -> None:
        pass


class BlasThreads:
    def build(self) -> BlasThreadsWorker:
        return BlasThreadsWorker()


@pytest.mark.parametrize("user_setting", [None, "3"])
def test_the_pool_processes_use_one_blas_thread_unless_the_user_said(
    private_tmp, monkeypatch, user_setting
):
    """The processes fill the cores: BLAS threads beside them would only spin. A count the
    user set is kept, and this process's own environment is left as it was."""
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS"):
        monkeypatch.delenv(name, raising=False)
    if user_setting is not None:
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", user_setting)
    with make_pool(BlasThreads(), 2) as pool:
        answers = {result for _, result in pool.imap(range(4))}
    assert answers == {(user_setting or "1", "1")}
    assert os.environ.get("OPENBLAS_NUM_THREADS") == user_setting
    assert "OMP_NUM_THREADS" not in os.environ


def wait_for_ever() -> None:
    """A preparation that never ends."""
    while True:
        time.sleep(1.0)


def test_closing_a_pool_given_no_task_does_not_wait_for_its_preparation(private_tmp):
    """An error or Ctrl-C while the parent prepares ends the pool at once: its processes, still
    preparing, are terminated (nothing left behind)."""
    pool = ProcessPool(None, 2, prepare=wait_for_ever)
    started = set(multiprocessing.active_children())
    closing = threading.Thread(target=pool.close)
    closing.start()
    closing.join(60.0)  # a guard against a hang, not a timing
    assert not closing.is_alive()
    assert not started & set(multiprocessing.active_children())
    assert list(private_tmp.iterdir()) == []


class InterruptsAsItIsSent:
    """A worker factory that sends Ctrl-C to the parent while it is sent to a starting process
    (pickled by the parent as the process starts)."""

    def __getstate__(self) -> dict:
        os.kill(os.getpid(), signal.SIGINT)
        return {}

    def build(self) -> PidWorker:
        return PidWorker()


def test_a_ctrl_c_while_the_processes_start_is_not_lost(private_tmp):
    """Another thread (numpy's BLAS threads in a campaign) may receive the signal: it must reach
    the parent's handler, and nothing may be left running."""
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    before = set(multiprocessing.active_children())
    try:
        with pytest.raises(KeyboardInterrupt):
            ProcessPool(InterruptsAsItIsSent(), 2)
    finally:
        release.set()
        other.join()
    assert not set(multiprocessing.active_children()) - before
    assert list(private_tmp.iterdir()) == []


class Sleeper:
    """A worker that sleeps ``task`` seconds (a long run)."""

    def __call__(self, task: float) -> float:
        time.sleep(task)
        return task

    def close(self) -> None:
        pass


class Sleepers:
    def build(self) -> Sleeper:
        return Sleeper()


def test_a_ctrl_c_while_tasks_run_ends_the_pool_without_awaiting_them(private_tmp):
    """The parent waits for results; a Ctrl-C interrupts that wait, and closing the pool kills
    the running tasks instead of awaiting their end (an hour here)."""
    pool = ProcessPool(Sleepers(), 2)
    results = pool.imap([0.0, 3600.0, 3600.0])
    assert next(results)[1] == 0.0
    sender = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    sender.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            next(results)
    finally:
        sender.join()
    closing = threading.Thread(target=pool.close)
    closing.start()
    closing.join(60.0)  # a guard against a hang, not a timing
    assert not closing.is_alive()
    assert list(private_tmp.iterdir()) == []


def test_closing_a_pool_kills_the_tasks_it_started_ahead_and_no_one_awaited(private_tmp):
    """An error before the started tasks' results were wanted (an hour each here): closing the
    pool kills them instead of awaiting their end."""
    pool = ProcessPool(Sleepers(), 2)
    started = pool.start([3600.0, 3600.0, 3600.0], Sleepers())
    time.sleep(0.5)
    closing = threading.Thread(target=pool.close)
    closing.start()
    closing.join(60.0)  # a guard against a hang, not a timing
    assert not closing.is_alive()
    assert not any(
        f.done() and not f.cancelled() and f.exception() is None for f in started.futures
    )
    assert list(private_tmp.iterdir()) == []


def test_stale_pool_folder_of_a_dead_process_is_removed(short_scenario, private_tmp):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = private_tmp / f"twin-pool-{dead.pid}-abc"
    (stale / "tmpx").mkdir(parents=True)
    mine = private_tmp / f"twin-pool-{os.getppid()}-abc"  # a live process: kept
    mine.mkdir()
    with command_temp_folder() as folder:
        assert tempfile.gettempdir() == folder
        pool = make_pool(ObjectiveSpec((load_scenario(short_scenario),), None, None), 1)
        pool.close()
    assert sorted(p.name for p in private_tmp.iterdir()) == [mine.name]


def start_twin(args: list[str], tmp: Path) -> subprocess.Popen:
    """``python -m twin_cosim ARGS`` in its own process group (a terminal's job), its temporary
    files in ``tmp``."""
    env = {**os.environ, "TMPDIR": str(tmp)}
    return subprocess.Popen(
        [sys.executable, "-m", "twin_cosim", *args],
        cwd=ROOT,
        env=env,
        start_new_session=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def start_campaign(scenario: str, out: Path, tmp: Path) -> subprocess.Popen:
    return start_twin(
        ["optimize", scenario, "--method", "ce", "--budget", "2000", "--workers", "2"]
        + ["--quiet", "--out", str(out)],
        tmp,
    )


def wait_for_evaluations(process: subprocess.Popen, log: Path, count: int) -> None:
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and process.poll() is None:
        if log.exists() and len(log.read_text().splitlines()) >= count:
            return
        time.sleep(0.05)
    raise AssertionError(f"campaign did not reach {count} evaluations: {process.stderr.read()}")


@pytest.mark.parametrize(
    ("sent", "to_group"),
    [(signal.SIGTERM, False), (signal.SIGKILL, False), (signal.SIGINT, True)],
    ids=["sigterm-parent", "kill9-parent", "ctrl-c-group"],
)
def test_campaign_ends_cleanly_on_a_signal(short_scenario, tmp_path, sent, to_group):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = tmp_path / "campaign"
    process = start_campaign(short_scenario, out, tmp)
    try:
        wait_for_evaluations(process, out / "evaluations.jsonl", 1)
        if to_group:
            os.killpg(process.pid, sent)
        else:
            os.kill(process.pid, sent)
        process.wait(timeout=60)
        stderr = process.stderr.read()
        alive = wait_until_gone(process.pid, 15)
    finally:
        if live_in_group(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
    assert alive == [], f"processes left behind: {alive}"
    assert list(tmp.iterdir()) == [], "temp folders left behind"
    if sent != signal.SIGKILL:
        assert process.returncode == 128 + sent
        assert "Traceback" not in stderr
        assert f"--resume {out}" in stderr
        assert len(stderr.strip().splitlines()) == 1, stderr


MOMENTS = [round(random.Random(18).uniform(0.3, 6.0), 2) for _ in range(8)]


@pytest.fixture(scope="module")
def dask_scheduler():
    """A Dask cluster in this process, listening on 127.0.0.1: its scheduler's address."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=False,
        protocol="tcp",
        host="127.0.0.1",
        dashboard_address=None,
    ) as cluster:
        yield cluster.scheduler_address


def interrupt_after(process: subprocess.Popen, delay: float) -> tuple[int | None, str, list[int]]:
    """Ctrl-C to the process group after ``delay`` s; the exit status (None: it had ended
    before), stderr and the processes of the group still alive 15 s after its end."""
    try:
        process.wait(timeout=delay)
        return None, process.stderr.read(), []
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGINT)
    try:
        process.wait(timeout=60)  # a guard against a hang, not a timing
        alive = wait_until_gone(process.pid, 15)
    finally:
        if live_in_group(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
    return process.returncode, process.stderr.read(), alive


@pytest.mark.parametrize(
    ("kind", "delay"),
    [("fresh", d) for d in MOMENTS[:3]]
    + [("resumed", d) for d in MOMENTS[3:5]]
    + [("compare", d) for d in MOMENTS[5:7]]
    + [("dask", MOMENTS[7])],
)
def test_ctrl_c_at_random_moments_ends_every_campaign(
    short_scenario, tmp_path, kind, delay, request
):
    """Ctrl-C from start-up to the middle of the evaluations, on a fresh, a resumed and a
    compared campaign, local pool and Dask: exit 130 after a clean shutdown, one line, no
    process or temp folder left, a log that reads whole."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = tmp_path / "campaign"
    where = ["--workers", "2"]
    if kind == "dask":
        where = ["--scheduler", request.getfixturevalue("dask_scheduler")]
    optimize = ["optimize", short_scenario, "--method", "ga", "--budget", "100000", *where]
    args = [*optimize, "--quiet", "--no-plots", "--out", str(out)]
    if kind == "resumed":
        first = start_twin(args, tmp)
        wait_for_evaluations(first, out / "evaluations.jsonl", 1)
        assert interrupt_after(first, 0.0)[:1] == (130,)
        args = ["optimize", short_scenario, "--resume", str(out), *where, "--quiet", "--no-plots"]
    elif kind == "compare":
        campaign = tmp_path / "campaign.yaml"
        campaign.write_text(
            f"name: c\nscenario: {short_scenario}\nmethods: [ga]\nbudgets: {{ga: 100000}}\n"
        )
        args = ["compare", str(campaign), *where, "--quiet", "--no-plots", "--out", str(out)]
    status, stderr, alive = interrupt_after(start_twin(args, tmp), delay)
    assert status == 130, stderr
    assert alive == [], f"processes left behind: {alive}"
    assert "Traceback" not in stderr
    assert len(stderr.strip().splitlines()) == 1, stderr
    for log in out.glob("**/evaluations.jsonl"):
        assert all(json.loads(line) for line in log.read_text().splitlines())
    assert list(tmp.iterdir()) == [], "temp folders left behind"


def test_a_signal_in_a_deferred_block_is_raised_at_its_end():
    reached_the_end = False
    with pytest.raises(KeyboardInterrupt):
        with deferred_signals() as deferral:
            signal.raise_signal(signal.SIGINT)
            assert deferral.signum == signal.SIGINT
            reached_the_end = True
    assert reached_the_end


def test_a_signal_ignored_outside_stays_ignored():
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with deferred_signals():
            signal.raise_signal(signal.SIGINT)
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_wait_ends_on_a_signal_from_another_thread():
    """The wait never answers: only the signal ends it, as a KeyboardInterrupt."""
    sender = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    sender.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            wait_interruptibly(lambda timeout_s: threading.Event().wait(timeout_s) or None)
    finally:
        sender.join()


def test_a_second_signal_is_absorbed_while_the_first_is_handled():
    """``timeout -s INT`` signals a command, then its group: the shutdown the first signal began
    (its ``finally`` and ``except`` blocks) runs to its end."""
    shut_down = False
    with stop_handlers():
        try:
            signal.raise_signal(signal.SIGINT)
            pytest.fail("not raised")
        except KeyboardInterrupt:
            signal.raise_signal(signal.SIGINT)  # during the shutdown: absorbed
            signal.raise_signal(signal.SIGTERM)
            shut_down = True
    assert shut_down
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


class Dropped:
    """An object whose finalizer receives the Ctrl-C (Python drops what it raises there)."""

    def __del__(self) -> None:
        signal.raise_signal(signal.SIGINT)


@pytest.mark.filterwarnings("error::pytest.PytestUnraisableExceptionWarning")
def test_a_ctrl_c_python_dropped_stops_the_next_wait():
    """Seen on a Dask campaign: the Ctrl-C landed in a weakref callback, Python printed
    "Exception ignored in ... Traceback" and the campaign ran to its end. Now it says nothing
    (no unraisable exception reaches the hook before) and the next wait raises the stop."""
    with stop_handlers():
        Dropped()  # its finalizer runs here, and the KeyboardInterrupt it raises is dropped
        with pytest.raises(KeyboardInterrupt):
            wait_interruptibly(lambda timeout_s: "answered")
