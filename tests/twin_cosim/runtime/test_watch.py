"""The live page of ``twin watch --dashboard`` in headless Chromium: served on 127.0.0.1 only,
it draws the gap and the tracked effects per window, the last window's twin against the
machine and the alarms with their diagnosis, and follows the state as windows arrive.

The page is looked at as a person would: a screenshot is written beside the DOM
(``TWIN_DASHBOARD_SHOT=FILE`` keeps a copy to look at)."""

from __future__ import annotations

import os
import shutil
import subprocess
import urllib.request
from pathlib import Path

import numpy as np
from runtime_cases import free_port

from twin_cosim.runtime.watch import Dashboard

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--virtual-time-budget=4000",
]


def chromium(url: str, profile: Path, *what: str) -> str:
    """Chromium's stdout after loading ``url`` (``--dump-dom`` or ``--screenshot=FILE``)."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    assert browser, "chromium is missing: scripts/setup.sh installs it"
    command = [browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *what, url]
    done = subprocess.run(command, capture_output=True, text=True, timeout=60)
    return done.stdout


def watch_state(windows: int) -> dict:
    """A watch's state after ``windows`` windows: friction drifting from window 6, alarmed at
    window 9 and diagnosed."""
    t = np.linspace(0.0, 1.3, 200)
    position = 0.004 * np.sin(np.pi * t / 1.3)
    rows = []
    for k in range(windows):
        drift = max(0, k - 5) * 0.0125
        rows.append(
            {
                "window": k,
                "sequence": k + 1,
                "real_time_factor": 11.0 + 0.1 * k,
                "phase": "baseline" if k < 4 else "watch",
                "gap": 1.05 + 0.4 * max(0, k - 5),
                "unexplained": None if k < 4 else 1.02,
                "values": {"coulomb_change": drift, "backlash_change": 1e-8 * (k % 2)},
            }
        )
    alarm = {
        "window": 9,
        "text": "drift alarm at window 9 (Sequence 10): coulomb_change drifts (delta_coulomb "
        "+12.5 mN.m per window since window 6; now +50 mN.m from the baseline)",
        "diagnosis": {"effect": "coulomb_change", "gap_before": 2.61, "gap_after": 1.04},
    }
    return {
        "windows": rows,
        "alarms": [alarm] if windows > 9 else [],
        "last": {
            "window": windows - 1,
            "t": t.tolist(),
            "position": position.tolist(),
            "twin_position": (position * 0.995).tolist(),
            "current": (0.8 * np.cos(np.pi * t / 1.3)).tolist(),
            "twin_current": (0.78 * np.cos(np.pi * t / 1.3)).tolist(),
        },
        "units": {"coulomb_change": "N.m", "backlash_change": "m"},
        "status": "watching opc.tcp://127.0.0.1:4840",
    }


def test_the_page_draws_the_watch_and_follows_it(tmp_path) -> None:
    dashboard = Dashboard(free_port())
    dashboard.state = watch_state(12)
    dashboard.start()
    try:
        assert dashboard.server.server_address[0] == "127.0.0.1"
        with urllib.request.urlopen(dashboard.url + "state.json", timeout=10) as answer:
            assert answer.headers["Content-Type"] == "application/json"
        dom = chromium(dashboard.url, tmp_path / "profile", "--dump-dom")
        shot = tmp_path / "dashboard.png"
        chromium(
            dashboard.url, tmp_path / "profile", f"--screenshot={shot}", "--window-size=1400,1000"
        )
        dashboard.state = watch_state(13)  # a window arrives
        later = chromium(dashboard.url, tmp_path / "profile", "--dump-dom")
    finally:
        dashboard.stop()
    assert "12 windows checked; last: window 11 (Sequence 12), real-time factor 12.1" in dom
    assert "coulomb_change drifts (delta_coulomb +12.5 mN.m per window" in dom
    assert "diagnosis: coulomb_change, held-out gap 2.61" in dom
    assert "Last window (11)" in dom and "coulomb_change [mN.m]" in dom and "[um]" in dom
    # the gap, the gap left, position and current (two each), and one chart per effect
    drawn = dom.split("<script>")[0]  # the page as drawn, without its script's text
    assert drawn.count("<path") == 2 + 4 + 2 and drawn.count("<svg") == 5
    assert "13 windows checked; last: window 12" in later and "Last window (12)" in later
    assert shot.stat().st_size > 20_000
    if os.environ.get("TWIN_DASHBOARD_SHOT"):
        shutil.copy(shot, os.environ["TWIN_DASHBOARD_SHOT"])


def test_a_port_taken_is_one_clear_error(tmp_path) -> None:
    first = Dashboard(free_port())
    try:
        port = first.server.server_address[1]
        try:
            Dashboard(port)
        except OSError as exc:
            assert f"--dashboard {port}: cannot listen on 127.0.0.1" in str(exc)
        else:
            raise AssertionError("a second server on a taken port")
    finally:
        first.server.server_close()
