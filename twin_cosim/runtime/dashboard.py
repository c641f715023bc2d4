"""The live page of ``twin watch --dashboard PORT``: served on 127.0.0.1 only, the gap and the
tracked effects' values per window, the last window's twin against the machine, and the
alarms, updating as windows arrive.

The page is one HTML file with its script inline (``dashboard.html`` beside this module; no
file or library from elsewhere): it asks ``/state.json`` every second and draws SVG charts.
The server is the standard library's HTTP server in a thread of its own, serving the
watch's latest state (a dictionary the watch replaces whole after each window, so a reader
never sees half an update).
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from twin_cosim.runtime.watch_log import READABLE, plain

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
