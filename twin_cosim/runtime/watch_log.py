"""The log of ``twin watch``: ``DIR/windows.jsonl``, one JSON object a line, for people and other
tools, and the numbers of it as people read them.

A window is ``{"window": N, "sequence": S, "real_time_factor": R, ...}`` (N counted from 0 in the
order received, S the server's Sequence); every other line is an event,
``{"event": KIND, ...}``: ``connected``, ``lost``, ``restored``, ``restarted``, ``missed``,
``skipped``, ``baseline``, ``alarm``, ``diagnosis``, ``twin_namespace`` and the last line
``end``. Each line is written whole and flushed, so that the log read at any time (or after a
signal) is complete up to its last line. docs/runtime.md lists every key.

What ``twin watch`` leaves beside its log: the trend plot (``trend.png``: the tracked
effects' values and the gap per window, the baseline shaded, each alarm marked) and the report
(``report.md``), both read from the log alone, so that they can be made again from any log.
"""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.gap.verdict import number
from twin_cosim.schema import json_lines

LOG_NAME = "windows.jsonl"
# How people read a tracked value: unit -> (factor, unit shown).
READABLE = {"N.m": (1e3, "mN.m"), "m": (1e6, "um"), "1": (100.0, "%"), "s": (1e3, "ms")}


def plain(value: Any) -> Any:
    """``value`` as JSON holds it: numpy numbers as Python numbers, non-finite floats as None,
    tuples as lists."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class WindowLog:
    """The JSONL log, written whole line by line (from any thread)."""

    def __init__(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._file = path.open("w", encoding="utf-8")
        self._lock = threading.Lock()

    def write(self, entry: dict[str, Any]) -> None:
        """Append one object as a line and flush it."""
        line = json.dumps(plain(entry), separators=(",", ":")) + "\n"
        with self._lock:
            if not self._file.closed:
                self._file.write(line)
                self._file.flush()

    def close(self) -> None:
        """Close the file (later writes are dropped)."""
        with self._lock:
            self._file.close()


def read_log(path: Path) -> list[dict[str, Any]]:
    """The objects of a log, in order.

    Raises
    ------
    ValueError
        Naming the file and line of a line that is not a JSON object.
    """
    entries = []

    def corrupt(line: int, exc: json.JSONDecodeError) -> str:
        return f"{path}:{line}: not a JSON object ({exc.msg})"

    with path.open(encoding="utf-8") as file:
        for number, entry in json_lines(file, corrupt):
            if not isinstance(entry, dict):
                raise ValueError(f"{path}:{number}: not a JSON object")
            entries.append(entry)
    return entries


def readable(value: float, unit: str) -> tuple[float, str]:
    """A value in the unit people read it in (mN.m, um, %)."""
    factor, shown = READABLE.get(unit, (1.0, unit))
    return value * factor, shown


def quantity(value: float, unit: str, signed: bool = False) -> str:
    """``+3.13 mN.m``: a value with its readable unit."""
    shown, text = readable(value, unit)
    sign = "+" if signed and shown > 0 else ""
    return f"{sign}{number(shown)} {text}".strip()


TREND_NAME = "trend.png"
REPORT_NAME = "report.md"


def _windows(entries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [e for e in entries if "event" not in e]


def _events(entries: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [e for e in entries if e.get("event") == kind]


def trend_series(entries: list[dict[str, Any]]) -> dict[str, Any]:
    """Per tracked parameter, and for the gaps: (windows, values), the baseline windows'
    values from the baseline line (after calibration) and the later ones from theirs."""
    baseline = next(iter(_events(entries, "baseline")), None)
    windows = _windows(entries)
    series: dict[str, tuple[list[int], list[float]]] = {}
    gap: tuple[list[int], list[float]] = ([], [])
    unexplained: tuple[list[int], list[float]] = ([], [])
    calibrated_gaps = baseline["gaps"] if baseline else {}
    for entry in windows:
        n = entry["window"]
        value = calibrated_gaps.get(str(n), entry["gap"]["normalised"])
        gap[0].append(n)
        gap[1].append(value)
        values = entry["values"] or (baseline["values"].get(str(n), {}) if baseline else {})
        for name, v in values.items():
            if name == "unexplained":
                continue
            series.setdefault(name, ([], []))
            series[name][0].append(n)
            series[name][1].append(v)
        left = entry["unexplained"]
        if left is None and baseline:
            left = baseline["values"].get(str(n), {}).get("unexplained")
        if left is not None:
            unexplained[0].append(n)
            unexplained[1].append(left)
    return {
        "effects": series,
        "gap": gap,
        "unexplained": unexplained,
        "units": baseline["units"] if baseline else {},
        "baseline_windows": baseline["windows"] if baseline else [],
        "tests": baseline["tests"] if baseline else {},
    }


def draw_trend(entries: list[dict[str, Any]], path: Path) -> None:
    """The trend plot: one panel per tracked parameter and one of the gaps, per window."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = trend_series(entries)
    alarms = _events(entries, "alarm")
    names = list(data["effects"])
    panels = len(names) + 1
    figure, axes = plt.subplots(panels, 1, figsize=(9, 1.8 * panels + 0.8), sharex=True)
    axes = np.atleast_1d(axes)
    span = data["baseline_windows"]
    for ax, name in zip(axes, names, strict=False):
        w, v = data["effects"][name]
        unit = data["units"].get(name, "")
        shown, label = readable(1.0, unit)
        ax.plot(w, np.array(v) * shown, ".-", color="tab:blue", lw=1, ms=3)
        test = data["tests"].get(name)
        if test:
            mean, spread = test["mean"] * shown, test["spread"] * shown
            ax.axhspan(mean - 3 * spread, mean + 3 * spread, color="tab:blue", alpha=0.12, lw=0)
        effect, _, parameter = name.partition(".")
        ax.set_ylabel(f"{parameter}\n[{label}]", fontsize=8)
        ax.set_title(effect, fontsize=9, loc="left")
    ax = axes[-1]
    # the gap drawn wide under the gap left, which often covers it (nothing drifts)
    ax.plot(*data["gap"], ".-", color="tab:gray", lw=3, ms=6, label="gap to the twin")
    if data["unexplained"][0]:
        ax.plot(
            *data["unexplained"],
            ".-",
            color="tab:orange",
            lw=1,
            ms=3,
            label="gap the tracked effects leave",
        )
    ax.axhline(1.0, color="k", lw=0.6, ls=":")
    ax.set_ylabel("normalised RMS\n[x noise floor]", fontsize=8)
    ax.set_title("gap", fontsize=9, loc="left")
    ax.legend(fontsize=7, loc="upper left")
    ax.set_xlabel("window")
    for ax in axes:
        if span:
            ax.axvspan(span[0] - 0.5, span[-1] + 0.5, color="tab:green", alpha=0.1, lw=0)
        for alarm in alarms:
            ax.axvline(alarm["window"], color="tab:red", lw=1.2)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
    title = "twin watch: tracked effects and gap per window (green: baseline; band: +/-3 spreads"
    title += "; red: alarm)" if alarms else ")"
    figure.suptitle(title, fontsize=10)
    for alarm in alarms:
        axes[0].annotate(
            f"alarm: {alarm['effect']}",
            (alarm["window"], 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(4, -12),
            textcoords="offset points",
            color="tab:red",
            fontsize=8,
        )
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def report_text(entries: list[dict[str, Any]]) -> str:
    """The report: what was watched, the baseline, the alarms and their diagnoses, the
    windows missed or skipped, the real-time factors."""
    windows = _windows(entries)
    baseline = next(iter(_events(entries, "baseline")), None)
    end = next(iter(_events(entries, "end")), {})
    factors = np.array([w["real_time_factor"] for w in windows if w["real_time_factor"]])
    lines = ["# twin watch", ""]
    lines.append(
        f"Windows received {end.get('received', len(windows))}, checked {len(windows)}, "
        f"skipped {end.get('skipped', 0)}, missed {end.get('missed', 0)}; "
        f"ended by {end.get('reason', 'an interruption before the end line')}."
    )
    if len(factors):
        lines.append(
            f"Real-time factor (window duration over the time to check it): median "
            f"{number(float(np.median(factors)))}, worst {number(float(np.min(factors)))}."
        )
    lines.append("")
    if baseline:
        lines.append("## Baseline")
        how = "calibrated on them" if baseline["calibrated"] else "the given plant parameters"
        lines.append(
            f"Windows {baseline['windows'][0]}-{baseline['windows'][-1]} ({how}, "
            f"{number(baseline['calibration_s'])} s); noise floors "
            f"{number(baseline['noise_floor_position_um'])} um and "
            f"{number(baseline['noise_floor_current_ma'])} mA; the tests designed for an "
            f"average run length of {number(baseline['design_arl_windows'])} windows to a "
            "false alarm."
        )
        if baseline["corrections"]:
            corrections = ", ".join(
                f"{k} {number(100 * v)} %" for k, v in baseline["corrections"].items()
            )
            lines.append(f"Calibration: {corrections}.")
        lines.append("")
        lines.append("| statistic | baseline mean | spread | threshold [spreads] |")
        lines.append("|---|---|---|---|")
        for name, test in baseline["tests"].items():
            unit = baseline["units"].get(name, "1")
            mean, shown = readable(test["mean"], unit)
            spread, _ = readable(test["spread"], unit)
            lines.append(
                f"| {name} | {number(mean)} {shown} | {number(spread)} {shown} | "
                f"{number(test['threshold'])} |"
            )
        lines.append("")
    alarms = _events(entries, "alarm")
    diagnoses = {d.get("alarm"): d for d in _events(entries, "diagnosis")}
    lines.append("## Alarms")
    if not alarms:
        lines.append("None.")
    for alarm in alarms:
        lines.append(f"- {alarm['text']}")
        found = diagnoses.get(alarm["alarm"])
        if found and not found.get("failed"):
            tried = found["hypotheses"]
            tried = tried if isinstance(tried, str) else ", ".join(tried)
            lines.append(
                f"  - full diagnosis on window {found['window']} ({number(found['wall_s'])} s, "
                f"hypotheses {tried}"
                f", held out: {found['held_out']}): {found['effect'] or 'no effect accepted'}; "
                f"held-out gap {number(found['gap_before'])} -> {number(found['gap_after'])} "
                "times the noise floor"
            )
        elif found:
            lines.append(f"  - full diagnosis failed: {found['text']}")
    lines.append("")
    skipped = _events(entries, "skipped")
    missed = _events(entries, "missed")
    if skipped or missed:
        lines.append("## Windows skipped or missed")
        lines += [f"- skipped {s['reason']}" for s in skipped]
        lines += [
            f"- {m['count']} missed between Sequence {m['after_sequence']} and "
            f"{m['before_sequence']}"
            for m in missed
        ]
        lines.append("")
    return "\n".join(lines) + "\n"


def write_report(log: Path, out: Path, plots: bool = True) -> list[Path]:
    """Write the report (and the trend plot) of a log into ``out``; the files written."""
    entries = read_log(log)
    report = out / REPORT_NAME
    report.write_text(report_text(entries))
    files = [log, report]
    if plots and _windows(entries):
        draw_trend(entries, out / TREND_NAME)
        files.append(out / TREND_NAME)
    return files
