"""The append-only log of a campaign's evaluations, which is also its checkpoint.

Each completed evaluation is appended as one JSON line and flushed to the operating system at
once, so a process that dies, even by ``kill -9`` in the middle of a generation, loses no
completed evaluation; the campaign syncs the file to disk (fsync) after every generation, so a
crash of the machine itself loses at most the generation under way. A campaign
resumes by replaying its optimizer from the seed: every batch the optimizer asks for again is
answered from this log, keyed by the exact bits of the candidate, and only what is missing is
computed. A torn last line (the write that was cut off) is ignored.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

REQUIRED_KEYS = frozenset({"key", "x", "fitness"})


def candidate_key(x: np.ndarray) -> str:
    """Exact identity of a candidate: the hex of its float64 bytes."""
    return np.ascontiguousarray(x, dtype=np.float64).tobytes().hex()


class EvaluationLog:
    """Evaluations of one campaign on disk (``evaluations.jsonl``) and in memory.

    Parameters
    ----------
    path
        The log file; existing complete lines are loaded.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.entries: list[dict[str, Any]] = []
        self._by_key: dict[str, dict[str, Any]] = {}
        if self.path.exists():
            self._load()
        self._file = self.path.open("a")

    def _load(self) -> None:
        try:
            text = self.path.read_text()
        except UnicodeDecodeError as exc:
            line = self.path.read_bytes()[: exc.start].count(b"\n") + 1
            raise ValueError(
                f"{self.path}: line {line}: not text (corrupt evaluation log): {exc.reason}"
            ) from None
        lines = text.split("\n")
        complete = lines[:-1] if not text.endswith("\n") else lines
        for number, line in enumerate(complete, start=1):
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ValueError(
                    f"{self.path}: line {number}: corrupt line in the evaluation log: {exc}"
                ) from exc
            missing = REQUIRED_KEYS - set(entry) if isinstance(entry, dict) else REQUIRED_KEYS
            if missing:
                raise ValueError(
                    f"{self.path}: line {number}: not an evaluation (expected a JSON object with "
                    f"{sorted(REQUIRED_KEYS)}; missing {sorted(missing)})"
                )
            self.entries.append(entry)
            self._by_key[entry["key"]] = entry
        # Drop a torn final line so that appends start on a fresh line.
        valid = "".join(line + "\n" for line in complete if line.strip())
        if valid != text:
            self.path.write_text(valid)

    def __len__(self) -> int:
        return len(self.entries)

    def lookup(self, x: np.ndarray) -> dict[str, Any] | None:
        """The logged result of candidate ``x``, or None."""
        return self._by_key.get(candidate_key(x))

    def append(self, x: np.ndarray, result: dict[str, Any], generation: int) -> dict[str, Any]:
        """Log one completed evaluation (flushed: it outlives this process); returns the stored
        entry."""
        entry = {
            "key": candidate_key(x),
            "x": [float(v) for v in x],
            "generation": generation,
            **result,
        }
        self._file.write(json.dumps(entry) + "\n")
        self._file.flush()
        self.entries.append(entry)
        self._by_key[entry["key"]] = entry
        return entry

    def sync(self) -> None:
        """Write what was appended to disk (it outlives a crash of the machine)."""
        os.fsync(self._file.fileno())

    def close(self) -> None:
        """Sync and close the file."""
        if not self._file.closed:
            self.sync()
        self._file.close()
