"""``twin watch``: the twin beside the running machine.

Three tasks share one event loop: the link reads each window off the server
(:mod:`twin_cosim.runtime.opcua`) into a short queue; the checker takes them in order and runs
the tracker on each (:mod:`twin_cosim.runtime.tracker`; in a process of its own that owns the
plant, so that a replay never holds up the link's reading); an alarm starts its diagnosis in
another process (:func:`run_alarm_diagnosis`, below), whose answer joins the log when
it comes. The queue
absorbs a slow window (the calibration); a checker slower than the machine for long fills it,
the link then reads late and counts the windows it missed. Everything goes to the log
(:mod:`twin_cosim.runtime.watch_log`) as it happens, alarms also to stderr and, when the server
allows it, into its twin namespace; the live page (:class:`Dashboard`) shows the same.

SIGINT and SIGTERM stop the watch at once: the window being checked is dropped, a running
diagnosis is ended, the log gets its ``end`` line, and the command exits 130 or 143.

**The live page** of ``twin watch --dashboard PORT``: served on 127.0.0.1 only, the gap and the
tracked effects' values per window, the last window's twin against the machine, and the
alarms, updating as windows arrive.

The page is one HTML file with its script inline (``dashboard.html`` beside this module; no
file or library from elsewhere): it asks ``/state.json`` every second and draws SVG charts.
The server is the standard library's HTTP server in a thread of its own, serving the
watch's latest state (a dictionary the watch replaces whole after each window, so a reader
never sees half an update).

**The alarm's diagnosis**: the full diagnosis an alarm asks for, restricted to what the alarm points
at and to the recent windows, run in a process of its own while the twin keeps checking windows.

What it runs: :func:`twin_cosim.gap.diagnosis.diagnose` (the whole pipeline: floors, where,
rounds of fits judged on held-out data against the noise and calibration floors) of the
baseline twin, with one effect at most and the hypotheses near the alarmed one: the tracked
effects (the alarmed one among them), or the plant model's whole library for an alarm on the
unexplained gap. The data: the first window from the alarm's on whose gap is at least
:data:`DIAGNOSABLE_GAP` times the noise floor (the sequential test sees a drift of a fraction
of the noise floor that no single window can show: the diagnosis waits for one that can, at
most :data:`LONGEST_WAIT` windows) and the one after it: the fit on the first, the judgement
on the second (a cycle's half may hold no reversal, which the diagnosis needs in each part);
when the two ran different references, or the wait ran out, the last window is split in
time. The calibration tolerance is how well the baseline calibration knows the calibrated
parameters (three of their standard errors, at least :data:`LEAST_TOLERANCE`; the datasheet
tolerance of the diagnosis when the baseline came from a plant file): a drift since the
baseline is not calibration error. Its replays run on :data:`WORKERS` processes. Its answer
joins the alarm: the effect accepted (or none), the held-out gap before and after it, and how
long it took (the wall time, and the diagnosis' own estimate of the wall time on otherwise
idle cores).
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.gap.verdict import number
from twin_cosim.measured import MeasuredRun
from twin_cosim.runtime.opcua import (
    LinkEvent,
    MachineLink,
    Missed,
    Notice,
    Received,
    Security,
    WindowError,
    window_of,
)
from twin_cosim.runtime.tracker import DEFAULT_TRACKED, UNEXPLAINED, Alarm, Tracker, WindowCheck
from twin_cosim.runtime.watch_log import LOG_NAME, READABLE, WindowLog, plain, quantity
from twin_cosim.runtime.window_replay import measured_run, window_case
from twin_cosim.scenario import Scenario

QUEUE_WINDOWS = 8  # windows read and waiting to be checked
DASHBOARD_POINTS = 1500  # samples of the last window the live page draws
DIAGNOSIS_NICENESS = 10


@dataclass(frozen=True)
class WatchOptions:
    """What ``twin watch`` is asked.

    Attributes
    ----------
    scenario : Scenario
        The scenario the machine runs (plant parameters of ``--plant-parameters`` applied).
    endpoint : str
        The machine's OPC UA endpoint.
    out : Path
        Folder of the log, the trend plot and the report.
    security : Security
        How to connect.
    axis : str
        The axis to follow.
    baseline : int
        Windows of the baseline.
    calibrate : bool
        Calibrate on them (False when ``--plant-parameters`` gives the baseline).
    tracked : tuple of str
        The tracked effects.
    windows : int or None
        Stop after this many windows received (None: until stopped).
    poll_s, reconnect_timeout_s : float
        The link's poll period and reconnection timeout, s.
    diagnose : bool
        Run the full diagnosis on an alarm.
    dashboard_port : int or None
        Serve the live page on 127.0.0.1 at this port.
    design_arl : float
        The tests' average run length to a false alarm, windows.
    fmu : str
        The plant FMU.
    quiet : bool
        No line per window on stdout.
    """

    scenario: Scenario
    endpoint: str
    out: Path
    fmu: str
    security: Security = field(default_factory=Security)
    axis: str = "X"
    baseline: int = 8
    calibrate: bool = True
    tracked: tuple[str, ...] = DEFAULT_TRACKED
    windows: int | None = None
    poll_s: float = 1.0
    reconnect_timeout_s: float = 60.0
    diagnose: bool = True
    dashboard_port: int | None = None
    design_arl: float = 10_000.0
    quiet: bool = False


@dataclass
class WatchSummary:
    """What a watch saw.

    Attributes
    ----------
    received, checked, skipped, missed : int
        Windows read, checked, skipped (bad data) and missed (never read).
    alarms : list of dict
        The alarm lines of the log, each with its diagnosis (``diagnosis``) when it came.
    real_time_factors : list of float
        Per checked window: its duration over the time to check it.
    stopped_by : int or None
        The signal that stopped the watch (None: it ended by itself).
    lost : str or None
        Why the link gave up (None: it did not).
    log : Path
        The JSONL log.
    """

    received: int = 0
    checked: int = 0
    skipped: int = 0
    missed: int = 0
    alarms: list[dict[str, Any]] = field(default_factory=list)
    real_time_factors: list[float] = field(default_factory=list)
    stopped_by: int | None = None
    lost: str | None = None
    log: Path = Path(LOG_NAME)
    baseline: dict[str, Any] | None = None


def alarm_line(alarm: Alarm) -> str:
    """An alarm as one line for people."""
    where = f"window {alarm.window} (Sequence {alarm.sequence})"
    if alarm.effect == UNEXPLAINED:
        return (
            f"drift alarm at {where}: the gap the tracked effects leave rose to "
            f"{number(alarm.value)} times the noise floor since window {alarm.since} "
            f"(baseline {number(alarm.baseline)})"
        )
    return (
        f"drift alarm at {where}: {alarm.effect} drifts ({alarm.parameter} "
        f"{quantity(alarm.rate, alarm.unit, signed=True)} per window since window {alarm.since}; "
        f"now {quantity(alarm.value - alarm.baseline, alarm.unit, signed=True)} from the baseline)"
    )


def alarm_entry(alarm: Alarm, number_: int) -> dict[str, Any]:
    """An alarm as its log line."""
    return {
        "event": "alarm",
        "alarm": number_,
        "window": alarm.window,
        "sequence": alarm.sequence,
        "effect": alarm.effect,
        "parameter": alarm.parameter,
        "unit": alarm.unit,
        "since_window": alarm.since,
        "rate_per_window": alarm.rate,
        "value": alarm.value,
        "baseline": alarm.baseline,
        "score": alarm.score,
        "also": alarm.also,
        "time": time.time(),
        "text": alarm_line(alarm),
    }


def window_entry(check: WindowCheck, duration: float, latency: float) -> dict[str, Any]:
    """A checked window as its log line."""
    gap = check.gap
    return {
        "window": check.window,
        "sequence": check.sequence,
        "real_time_factor": duration / check.check_s if check.check_s > 0 else None,
        "check_s": check.check_s,
        "duration_s": duration,
        "latency_s": latency,
        "phase": check.phase,
        "tested": check.tested,
        "starts_at_rest": check.starts_at_rest,
        "gap": {
            "normalised": gap.normalised_rms,
            "position_um": gap.position_rms_um,
            "current_ma": gap.current_rms_ma,
            "position_normalised": gap.position_normalised,
            "current_normalised": gap.current_normalised,
            "lies": gap.lies,
            "enrichment": gap.where,
        },
        "unexplained": check.unexplained,
        "values": check.values,
    }


class _Diagnoses:
    """The alarms' diagnoses: one process at a time, in the order of the alarms."""

    def __init__(self, write: Callable[[dict[str, Any]], None]) -> None:
        self.write = write
        self.waiting: deque[AlarmJob] = deque()
        self.running: tuple[Any, Any, AlarmJob, float] | None = None
        self.results: dict[int, dict[str, Any]] = {}

    def submit(self, job: AlarmJob) -> None:
        self.waiting.append(job)
        self._start_next()

    def _start_next(self) -> None:
        if self.running is not None or not self.waiting:
            return
        context = multiprocessing.get_context("spawn")
        job = self.waiting.popleft()
        queue = context.SimpleQueue()
        # not a daemon: its replay workers are its children (they die with it, see workers.py)
        process = context.Process(target=_diagnosis_process, args=(job, queue), daemon=False)
        process.start()
        self.running = (process, queue, job, time.perf_counter())

    def poll(self) -> None:
        """Log a finished diagnosis and start the next."""
        if self.running is None:
            return
        process, queue, job, started = self.running
        if queue.empty():
            if process.is_alive():
                return
            result: dict[str, Any] = {
                "event": "diagnosis",
                "alarm": job.alarm,
                "failed": True,
                "text": f"the diagnosis process ended ({process.exitcode})",
            }
        else:
            result = queue.get()
        result["wall_s"] = time.perf_counter() - started
        process.join(1.0)
        self.results[job.alarm] = result
        self.write(result)
        self.running = None
        self._start_next()

    def stop(self) -> None:
        """End a running diagnosis; drop those waiting."""
        self.waiting.clear()
        if self.running is not None:
            process = self.running[0]
            process.terminate()
            process.join(2.0)
            if process.is_alive():
                process.kill()
            self.running = None


def _diagnosis_process(job: AlarmJob, queue: Any) -> None:
    """A diagnosis process: runs the job, sends its result (or its error) back."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the watch stops it itself
    os.nice(DIAGNOSIS_NICENESS)  # the checker keeps up with the machine meanwhile
    try:
        queue.put(run_alarm_diagnosis(job))
    except Exception as exc:  # noqa: BLE001 - reported in the log, the watch goes on
        queue.put(
            {
                "event": "diagnosis",
                "alarm": job.alarm,
                "window": job.window,
                "failed": True,
                "text": f"{type(exc).__name__}: {exc}",
            }
        )


class _Checker:
    """The tracker in a process of its own (it owns the plant), so that the link's reading is
    never held up by a replay: requests and answers over a pipe."""

    def __init__(self, options: WatchOptions) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self.process = context.Process(
            target=_checker_main,
            args=(
                child,
                options.scenario,
                options.fmu,
                options.tracked,
                options.baseline,
                options.calibrate,
                options.design_arl,
            ),
            daemon=True,
        )
        self.process.start()
        child.close()
        self._lock = threading.Lock()

    def call(self, request: tuple) -> Any:
        """Send a request, wait for its answer (from a worker thread of the event loop)."""
        with self._lock:
            self._conn.send(request)
            kind, answer = self._conn.recv()
        if kind == "error":
            raise answer
        if kind == "failed":
            raise RuntimeError(f"the checker failed: {answer}")
        return answer

    def stop(self) -> None:
        """End the process."""
        self.process.terminate()
        self.process.join(2.0)
        if self.process.is_alive():
            self.process.kill()


def _checker_main(conn: Any, scenario, fmu, tracked, baseline, calibrate, design_arl) -> None:
    """The checker process: a tracker answering ``("check", index, window, label)`` with the
    check, its alarms and its CPU-side time, and ``("baseline",)`` with the baseline's log line."""
    import traceback

    from twin_cosim.plant import Plant

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the watch stops it itself
    with Plant(fmu) as plant:
        tracker = Tracker(scenario, plant, tracked, baseline, calibrate, design_arl)
        conn.send(("ok", None))
        while True:
            try:
                request = conn.recv()
            except EOFError:  # the watch has gone
                return
            try:
                if request[0] == "check":
                    started = time.perf_counter()
                    check, alarms = tracker.check(*request[1:])
                    elapsed = time.perf_counter() - started
                    answer: Any = (_with_time(check, elapsed), alarms, tracker.ready)
                else:
                    started = time.perf_counter()
                    tracker.make_baseline()
                    answer = tracker.describe_baseline() | {
                        "wall_s": time.perf_counter() - started,
                        "parameters": tracker.baseline.parameters,
                    }
                conn.send(("ok", answer))
            except WindowError as exc:
                conn.send(("error", exc))
            except Exception:  # noqa: BLE001 - sent to the watch, which stops with it
                conn.send(("failed", traceback.format_exc(limit=6)))


class Watch:
    """One watch: the link, the checker, the log, the diagnoses, the live page."""

    def __init__(self, options: WatchOptions) -> None:
        self.options = options
        self.summary = WatchSummary(log=options.out / LOG_NAME)
        self.log = WindowLog(options.out / LOG_NAME)
        self.diagnoses = _Diagnoses(self._logged_diagnosis)
        self.link = MachineLink(
            options.endpoint,
            options.axis,
            options.security,
            options.poll_s,
            options.reconnect_timeout_s,
        )
        self.dashboard: Any = None
        self.state: dict[str, Any] = {"windows": [], "alarms": [], "last": None, "status": ""}
        self._last: tuple[int, Any, Any] | None = None  # the last window: index, window, case
        self._index = 0
        self._read_done = False
        self._undiagnosed: list[tuple[Alarm, int]] = []
        self._diagnosable: tuple[int, Any, Any] | None = None  # the last window worth diagnosing

    def _say(self, text: str) -> None:
        if not self.options.quiet:
            print(text, flush=True)

    def _logged_diagnosis(self, result: dict[str, Any]) -> None:
        self.log.write(result)
        for alarm in self.summary.alarms:
            if alarm["alarm"] == result.get("alarm"):
                alarm["diagnosis"] = result
        if result.get("failed"):
            print(
                f"twin watch: warning: diagnosis of alarm {result.get('alarm')} failed: "
                f"{result.get('text')}",
                file=sys.stderr,
            )
        else:
            found = result["effect"] or "no effect of those tried"
            print(
                f"twin watch: diagnosis of alarm {result['alarm']} (window {result['window']}): "
                f"{found}; the held-out gap {number(result['gap_before'])} -> "
                f"{number(result['gap_after'])} times the noise floor "
                f"({number(result['wall_s'])} s)",
                file=sys.stderr,
            )
        self._publish()

    def _publish(self) -> None:
        """Hand the live page a new state (replaced whole: its server reads it meanwhile)."""
        if self.dashboard is not None:
            self.dashboard.state = {
                "windows": list(self.state["windows"]),
                "alarms": [dict(a) for a in self.summary.alarms],
                "last": self.state["last"],
                "units": self.state.get("units", {}),
                "status": self.state["status"],
            }

    async def run(self) -> WatchSummary:
        """Watch until the window limit, a signal, or the link gives up."""
        loop = asyncio.get_running_loop()
        if self.options.dashboard_port is not None:
            self.dashboard = Dashboard(self.options.dashboard_port)
            self.dashboard.start()
        queue: asyncio.Queue[LinkEvent | None] = asyncio.Queue(QUEUE_WINDOWS)
        checker_process = _Checker(self.options)
        self.checker = checker_process
        await loop.run_in_executor(None, checker_process._conn.recv)  # the plant is loaded
        reader = asyncio.create_task(self._read(queue))
        checker = asyncio.create_task(self._check(queue))
        stop = asyncio.Event()
        for signum in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(signum, self._stopped, signum, stop)
        waiter = asyncio.create_task(stop.wait())
        try:
            await asyncio.wait({checker, waiter}, return_when=asyncio.FIRST_COMPLETED)
            for task in (checker, reader):
                if task.done() and not task.cancelled() and task.exception() is not None:
                    raise task.exception()
        finally:
            for task in (reader, checker, waiter):
                task.cancel()
            await asyncio.gather(reader, checker, waiter, return_exceptions=True)
            for signum in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(signum)
            self.diagnoses.stop()
            checker_process.stop()
            self._finish()
        return self.summary

    def _stopped(self, signum: int, stop: asyncio.Event) -> None:
        if self.summary.stopped_by is None:
            self.summary.stopped_by = signum
        stop.set()

    def _finish(self) -> None:
        summary = self.summary
        reason = (
            f"signal {summary.stopped_by}"
            if summary.stopped_by
            else (summary.lost or "windows done")
        )
        self.log.write(
            {
                "event": "end",
                "reason": reason,
                "received": summary.received,
                "checked": summary.checked,
                "skipped": summary.skipped,
                "missed": summary.missed,
                "alarms": len(summary.alarms),
                "time": time.time(),
            }
        )
        self.log.close()
        if self.dashboard is not None:
            self.state["status"] = f"ended: {reason}"
            self._publish()
            self.dashboard.stop()

    async def _read(self, queue: asyncio.Queue) -> None:
        """The link's events into the queue (waiting while it is full), until the window
        limit or the link gives up; then the end mark."""
        from twin_cosim.runtime.opcua import LinkLost

        events = self.link.events()
        limit = self.options.windows
        try:
            async for event in events:
                await queue.put(event)
                if isinstance(event, Received):
                    self.summary.received += 1
                    if limit is not None and self.summary.received >= limit:
                        break
        except LinkLost as exc:
            self.summary.lost = str(exc)
            print(f"twin watch: {exc}", file=sys.stderr)
        finally:
            await events.aclose()
            self._read_done = True
            try:
                queue.put_nowait(None)
            except asyncio.QueueFull:
                pass  # the checker sees _read_done once the queue is empty

    async def _check(self, queue: asyncio.Queue) -> None:
        """Check the windows in order; log everything; start the alarms' diagnoses."""
        while True:
            try:
                event = await asyncio.wait_for(queue.get(), 0.5)
            except TimeoutError:
                self.diagnoses.poll()
                if self._read_done and queue.empty():
                    event = None
                else:
                    continue
            self.diagnoses.poll()
            if event is None:
                await self._drain_diagnoses()
                return
            if isinstance(event, Notice):
                self._notice(event)
            elif isinstance(event, Missed):
                self.summary.missed += event.count
                self.log.write(
                    {
                        "event": "missed",
                        "count": event.count,
                        "after_sequence": event.after,
                        "before_sequence": event.before,
                        "next_window": self._index,
                    }
                )
                print(
                    f"twin watch: warning: {event.count} window(s) missed between Sequence "
                    f"{event.after} and {event.before}",
                    file=sys.stderr,
                )
            else:
                await self._window(event)

    async def _drain_diagnoses(self) -> None:
        """Wait for the diagnoses still to come (the watch ended by its window limit)."""
        while self.diagnoses.running is not None:
            self.diagnoses.poll()
            await asyncio.sleep(0.2)

    def _notice(self, notice: Notice) -> None:
        self.log.write({"event": notice.kind, "text": notice.text, "time": time.time()})
        self.state["status"] = notice.text
        self._publish()
        if notice.kind in ("lost", "restarted", "twin_namespace"):
            print(f"twin watch: {notice.text}", file=sys.stderr)

    async def _window(self, event: Received) -> None:
        loop = asyncio.get_running_loop()
        index = self._index
        self._index += 1
        label = f"window {index} (Sequence {event.sequence})"
        try:
            window = window_of(event.sequence, event.arrays, label)
            check, alarms, ready = await loop.run_in_executor(
                None, self.checker.call, ("check", index, window, label)
            )
        except WindowError as exc:
            self.summary.skipped += 1
            self.log.write(
                {
                    "event": "skipped",
                    "window": index,
                    "sequence": event.sequence,
                    "reason": str(exc),
                }
            )
            print(f"twin watch: warning: skipped {exc}", file=sys.stderr)
            return
        self.summary.checked += 1
        entry = window_entry(check, window.duration, time.time() - event.received_at)
        self.summary.real_time_factors.append(entry["real_time_factor"])
        self.log.write(entry)
        self._remember(index, window, label)
        self._say(
            f"{label}: gap {number(check.gap.normalised_rms)} x noise floor"
            f" ({check.phase}), checked in {number(check.check_s)} s"
            f" (real-time factor {number(entry['real_time_factor'])})"
        )
        self._show(entry, window, check)
        if ready:
            baseline = await loop.run_in_executor(None, self.checker.call, ("baseline",))
            self.summary.baseline = baseline
            self.log.write({k: v for k, v in baseline.items() if k != "parameters"})
            self.state["units"] = baseline["units"]
            self._say(
                f"baseline of windows {baseline['windows'][0]}-{baseline['windows'][-1]} ready "
                f"({number(baseline['wall_s'])} s): watching for drift"
            )
        for alarm in alarms:
            self._alarm(alarm)
        self._ask_diagnoses(check)
        await self._write_twin(check)

    def _ask_diagnoses(self, check: WindowCheck) -> None:
        """Start the diagnosis of each alarm waiting for windows that can show its drift: two
        in a row of one reference whose gaps reach :data:`DIAGNOSABLE_GAP` (the first fits,
        the second judges), or the last one when the wait has run out."""
        index, window, case = self._last
        diagnosable = check.gap.normalised_rms >= DIAGNOSABLE_GAP
        before = self._diagnosable
        self._diagnosable = (index, window, case) if diagnosable else None
        for alarm, number_ in list(self._undiagnosed):
            paired = (
                diagnosable
                and before is not None
                and before[0] == index - 1
                and before[2].digest == case.digest
                and before[0] >= alarm.window
            )
            if paired or check.window - alarm.window >= LONGEST_WAIT:
                self._undiagnosed.remove((alarm, number_))
                self.diagnoses.submit(self._job(alarm, number_, before if paired else None))

    def _remember(self, index: int, window: Any, label: str) -> None:
        self._last = (index, window, window_case(self.options.scenario, window, label))

    def _alarm(self, alarm: Alarm) -> None:
        number_ = len(self.summary.alarms)
        entry = alarm_entry(alarm, number_)
        self.summary.alarms.append(entry)
        self.log.write(entry)
        print(f"twin watch: {entry['text']}", file=sys.stderr)
        self._publish()
        if self.options.diagnose:
            self._undiagnosed.append((alarm, number_))

    def _job(self, alarm: Alarm, number_: int, fit_on: tuple | None) -> AlarmJob:
        """The diagnosis of an alarm: fitted on ``fit_on`` and judged on the last window, or
        on the last window split in time."""
        index, window, case = self._last
        hypotheses = None if alarm.effect == UNEXPLAINED else tuple(self.options.tracked)
        assert self.summary.baseline is not None
        last = measured_run(window, f"window {index} (Sequence {window.sequence})")
        if fit_on is not None:
            first = measured_run(fit_on[1], f"window {fit_on[0]} (Sequence {fit_on[1].sequence})")
            training, holdout = first, last
        else:
            training, holdout = last, None
        return AlarmJob(
            number_,
            index,
            alarm.effect,
            with_baseline(case.scenario, self.summary.baseline["parameters"]),
            training,
            holdout,
            hypotheses,
            self.options.fmu,
            alarm.window,
            alarm_tolerance(self.summary.baseline["calibration_precision"]),
        )

    def _show(self, entry: dict[str, Any], window: Any, check: WindowCheck) -> None:
        """The live page's state: the windows' figures, the last window against the twin."""
        self.state["windows"].append(
            {k: entry[k] for k in ("window", "sequence", "real_time_factor", "phase", "values")}
            | {"gap": entry["gap"]["normalised"], "unexplained": entry["unexplained"]}
        )
        step = max(1, window.samples // DASHBOARD_POINTS)
        twin_x, twin_i = check.twin if check.twin is not None else (None, None)
        self.state["last"] = {
            "window": check.window,
            "t": (window.time[::step] - window.time[0]).tolist(),
            "position": window.position[::step].tolist(),
            "twin_position": twin_x[::step].tolist() if twin_x is not None else [],
            "current": window.current[::step].tolist(),
            "twin_current": twin_i[::step].tolist() if twin_i is not None else [],
        }
        self._publish()

    async def _write_twin(self, check: WindowCheck) -> None:
        """The window's figures (and the last alarm) into the server's twin namespace."""
        values: dict[str, Any] = {
            "Window": int(check.sequence),
            "Gap": float(check.gap.normalised_rms),
            "Alarms": len(self.summary.alarms),
        }
        if self.summary.alarms:
            import json

            values["Alarm"] = json.dumps(
                {k: v for k, v in self.summary.alarms[-1].items() if k != "diagnosis"}
            )
        await self.link.write_twin(values)


def _with_time(check: WindowCheck, elapsed: float) -> WindowCheck:
    import dataclasses

    return dataclasses.replace(check, check_s=elapsed)


def watch(options: WatchOptions) -> WatchSummary:
    """Run a watch to its end (see :class:`Watch`); the handlers of SIGINT and SIGTERM before it
    are restored after."""
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return asyncio.run(Watch(options).run())
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def rtf_figures(factors: list[float]) -> dict[str, float]:
    """Median and worst real-time factor of the checked windows."""
    values = np.array([f for f in factors if f is not None], dtype=float)
    if not len(values):
        return {}
    return {"median": float(np.median(values)), "worst": float(np.min(values))}


LOOPBACK = "127.0.0.1"

PAGE = Path(__file__).with_name("dashboard.html")  # the page, its script inline


class Dashboard:
    """The live page's HTTP server on 127.0.0.1.

    Parameters
    ----------
    port
        TCP port.

    Attributes
    ----------
    state : dict
        The watch's latest state, replaced whole by the watch: ``windows`` (per window:
        ``window``, ``sequence``, ``real_time_factor``, ``gap``, ``unexplained``,
        ``values``), ``alarms`` (their log lines), ``last`` (the last window's ``t``,
        ``position``, ``twin_position``, ``current``, ``twin_current``), ``units``,
        ``status``.
    """

    def __init__(self, port: int) -> None:
        self.state: dict[str, Any] = {"windows": [], "alarms": [], "last": None, "status": ""}
        page = PAGE.read_text().replace("__READABLE__", json.dumps(READABLE)).encode()
        owner = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 - the standard library's name
                if self.path in ("/", "/index.html"):
                    body, kind = page, "text/html; charset=utf-8"
                elif self.path.startswith("/state.json"):
                    body, kind = json.dumps(plain(owner.state)).encode(), "application/json"
                else:
                    self.send_error(404)
                    return
                self.send_response(200)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Cache-Control", "no-store")
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, format: str, *args: Any) -> None:
                return  # the watch's output is its own

        try:
            self.server = ThreadingHTTPServer((LOOPBACK, port), Handler)
        except OSError as exc:
            raise OSError(f"--dashboard {port}: cannot listen on {LOOPBACK} ({exc})") from None
        self.server.daemon_threads = True
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://{LOOPBACK}:{self.server.server_address[1]}/"

    def start(self) -> None:
        """Serve in a thread of its own."""
        self._thread.start()

    def stop(self) -> None:
        """Stop serving."""
        self.server.shutdown()
        self.server.server_close()


DIAGNOSABLE_GAP = 1.5  # normalised RMS gap of a window worth diagnosing
LONGEST_WAIT = 10  # windows after the alarm: the diagnosis runs then at the latest
LEAST_TOLERANCE = 0.001  # relative
WORKERS = 2  # replay processes of the diagnosis: the two cores of a small machine


def alarm_tolerance(precision: float | None) -> float:
    """The calibration tolerance of an alarm's diagnosis from the baseline calibration's
    precision (relative; None: no calibration, the diagnosis' own tolerance)."""
    from twin_cosim.gap.settings import DiagnosisSettings

    if precision is None:
        return DiagnosisSettings().calibration_tolerance
    return max(3.0 * precision, LEAST_TOLERANCE)


@dataclass(frozen=True)
class AlarmJob:
    """What the diagnosis of one alarm needs (sent to its process).

    Attributes
    ----------
    alarm : int
        The alarm's number (0 for the first).
    window : int
        The alarm's window.
    effect : str
        The alarmed effect (or ``unexplained``).
    scenario : Scenario
        The window's scenario with the baseline twin's plant parameters.
    training : MeasuredRun
        The window the effects are fitted on.
    holdout : MeasuredRun or None
        The window they are judged on (None: ``training`` is split in time).
    hypotheses : tuple of str or None
        The hypotheses to fit (None: the whole library).
    fmu : str
        The plant FMU.
    alarm_window : int
        The window at which the alarm was raised (``window`` may come later: the first whose
        gap is large enough to diagnose).
    calibration_tolerance : float
        How well the baseline twin's calibrated parameters are known (relative).
    """

    alarm: int
    window: int
    effect: str
    scenario: Scenario
    training: MeasuredRun
    holdout: MeasuredRun | None
    hypotheses: tuple[str, ...] | None
    fmu: str
    alarm_window: int
    calibration_tolerance: float


def with_baseline(scenario: Scenario, parameters: dict[str, float]) -> Scenario:
    """The scenario with the baseline twin's FMU parameters."""
    return dataclasses.replace(
        scenario, plant_parameters={**scenario.plant_parameters, **parameters}
    )


def run_alarm_diagnosis(job: AlarmJob) -> dict[str, Any]:
    """Run the diagnosis of one alarm; what the log records of it."""
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.gap.settings import DiagnosisSettings

    start = time.perf_counter()
    settings = DiagnosisSettings(
        max_effects=1, hypotheses=job.hypotheses, calibration_tolerance=job.calibration_tolerance
    )
    holdout = [job.holdout] if job.holdout is not None else []
    found = diagnose(job.scenario, [job.training], holdout, job.fmu, settings, workers=WORKERS)
    remaining = found.remaining
    accepted = [a if isinstance(a, str) else "+".join(a) for a in found.accepted]
    before, after = remaining.normalised_rms_before, remaining.times_noise_floor
    return {
        "event": "diagnosis",
        "alarm": job.alarm,
        "window": job.window,
        "alarm_window": job.alarm_window,
        "alarmed_effect": job.effect,
        "calibration_tolerance": job.calibration_tolerance,
        "hypotheses": list(job.hypotheses) if job.hypotheses else "library",
        "held_out": "the next window" if job.holdout is not None else "the window's second half",
        "significant": bool(found.significant),
        "accepted": accepted,
        "effect": accepted[0] if accepted else None,
        "agrees": bool(accepted) and job.effect in accepted[0].split("+"),
        "gap_before": before,
        "gap_after": after,
        "gap_shrinks_by": 1.0 - after / before if before > 0 else 0.0,
        "position_rms_um_before": remaining.position_rms_um_before,
        "position_rms_um_after": remaining.position_rms_um,
        "verdict": found.verdict,
        "seconds": time.perf_counter() - start,
        "idle_wall_s": found.times["diagnosis"]["idle_wall_estimate_s"],
        "workers": WORKERS,
    }


def warm_up() -> None:
    """Import what the diagnosis uses (a pool's initializer: the first alarm waits less)."""
    import twin_cosim.gap.diagnosis  # noqa: F401
