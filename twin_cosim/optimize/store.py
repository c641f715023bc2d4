"""A campaign's folder: its record, its evaluation log, its lock, progress and result files.

A campaign folder holds

- ``campaign.json``: the record of what was asked (the problem's spec, bounds, method settings,
  each case's reference run and the content fingerprints of the inputs); ``--resume`` reads it
  back and refuses a resume whose options or inputs differ, naming what changed. Paths do not
  count, contents do: a scenario moved to another folder still resumes, an edited one does not;
- ``evaluations.jsonl``: every completed evaluation, flushed at once (:class:`EvaluationLog`,
  the checkpoint);
- ``progress.json``: rewritten after every generation (generation, evaluations, best so far);
- ``result.json``: the outcome (best parameters and metrics, evaluations, wall time);
- ``campaign.lock``: while a campaign runs, the pid of the one process that writes the folder
  (:class:`FolderLock`).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import logging
import os
import zipfile
from collections.abc import Mapping
from dataclasses import MISSING, asdict, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from twin_cosim.schema import json_lines
from twin_cosim.workers import pid_alive

if TYPE_CHECKING:
    from twin_cosim.optimize.algorithms.base import Optimizer
    from twin_cosim.optimize.config import OptimizeConfig

LOG = logging.getLogger(__name__)
RECORD = "campaign.json"
LOCK_NAME = "campaign.lock"
# Options naming an input file by its path: its content is checked (the fingerprints), not its
# path, so a moved file resumes
PATH_OPTIONS = ("scenario", "fmu")
Spec = TypeVar("Spec")


class CampaignError(ValueError):
    """A campaign cannot start or resume; the message says why."""


def read_record(out_dir: Path, required: Mapping[str, type] | None = None) -> dict[str, Any]:
    """The record ``campaign.json`` of the campaign in ``out_dir``, checked for a ``spec``
    mapping and the keys its problem requires (``required``: the type of each)."""
    path = Path(out_dir) / RECORD
    if not path.is_file():
        raise CampaignError(f"{out_dir}: no campaign.json to resume from")
    try:
        record = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CampaignError(f"{path}: not a campaign record (JSON): {exc}") from exc
    if not isinstance(record, dict) or not isinstance(record.get("spec"), dict):
        raise CampaignError(f"{path}: not a campaign record: no 'spec' mapping")
    bad = sorted(
        key
        for key, kind in (required or {}).items()
        if key not in record or not isinstance(record[key], kind)
    )
    if bad:
        raise CampaignError(f"{path}: not a campaign record: missing or bad {bad}")
    return record


def load_spec(out_dir: Path, spec_type: type[Spec], required: Mapping[str, type]) -> Spec:
    """The spec (a ``spec_type``) of the campaign stored in ``out_dir`` (for ``--resume``);
    ``required``: the keys its record holds."""
    stored = read_record(out_dir, required)["spec"]
    try:
        return spec_type(**stored)
    except TypeError as exc:
        raise CampaignError(f"{Path(out_dir) / RECORD}: bad 'spec': {exc}") from exc


def write_record(out_dir: Path, record: dict[str, Any]) -> None:
    """Write a new campaign's record."""
    (Path(out_dir) / RECORD).write_text(json.dumps(record, indent=2) + "\n")


def refuse_a_campaign_in(out_dir: Path) -> None:
    """A new campaign needs a folder that holds none yet."""
    if (Path(out_dir) / RECORD).exists():
        raise CampaignError(
            f"{out_dir}: already holds a campaign; use --resume {out_dir} or another --out"
        )


def check_same_options(out_dir: Path, record: dict[str, Any], spec: Any) -> None:
    """Refuse a resume whose options (``spec``, a dataclass) differ from the stored campaign's,
    naming them.

    The options of :data:`PATH_OPTIONS` may be given under other paths: their contents are
    checked (:func:`check_same_inputs`).
    """
    defaults = {f.name: f.default for f in fields(spec) if f.default is not MISSING}
    stored = {k: v for k, v in record["spec"].items() if k not in PATH_OPTIONS}
    given = {k: v for k, v in asdict(spec).items() if k not in PATH_OPTIONS}
    differ = {  # a campaign stored before an option existed has that option's default
        k: (given.get(k, defaults.get(k)), stored.get(k, defaults.get(k)))
        for k in sorted(set(given) | set(stored))
        if given.get(k, defaults.get(k)) != stored.get(k, defaults.get(k))
    }
    if differ:
        raise CampaignError(
            f"{out_dir}: holds a different campaign; options differ from the stored campaign "
            f"(given, stored): {differ}"
        )


def check_same_inputs(
    out_dir: Path, record: dict[str, Any], found: dict[str, Any], names: dict[str, str]
) -> None:
    """Refuse a resume whose input contents differ from the stored campaign's.

    ``found`` are the inputs' content fingerprints now, ``names`` what a message calls each
    (by the fingerprint's key).
    """
    recorded = record.get("fingerprints")
    if not isinstance(recorded, dict):
        raise CampaignError(
            f"{out_dir}/campaign.json: holds no content fingerprints (an older campaign), so "
            "a resume cannot be checked against it; start a new campaign"
        )
    changed = [names[key] for key in names if recorded.get(key) != found[key]]
    if changed:
        raise CampaignError(
            f"{out_dir}: cannot resume: the {' and the '.join(changed)} changed since the "
            f"campaign started (content fingerprints differ); start a new campaign in another "
            "--out, or resume with the original inputs"
        )


def digest(*parts: bytes) -> str:
    """A content fingerprint of ``parts`` (the hash of their hashes: parts never run together)."""
    hasher = hashlib.sha256()
    for part in parts:
        hasher.update(hashlib.sha256(part).digest())
    return hasher.hexdigest()


def fmu_fingerprint(fmu: Path) -> str:
    """The FMU's member names and contents (not the archive's timestamps)."""
    if not fmu.is_file() or not zipfile.is_zipfile(fmu):
        raise CampaignError(f"{fmu}: plant FMU not found or not an FMU (zip archive)")
    with zipfile.ZipFile(fmu) as archive:
        names = sorted(info.filename for info in archive.infolist() if not info.is_dir())
        return digest(*(part for name in names for part in (name.encode(), archive.read(name))))


def settings_fingerprint(settings: dict[str, Any]) -> str:
    """Method, seed, budget, method settings and the checked ``optimize`` section."""
    return digest(json.dumps(settings, sort_keys=True, default=str).encode())


def write_progress(
    out_dir: Path, optimizer: Optimizer, config: OptimizeConfig, elapsed: float
) -> None:
    """Rewrite ``progress.json`` (atomically): generation, evaluations, best so far, time (s)."""
    best_unit, best_fitness = optimizer.best
    progress = {
        "generation": optimizer.generation,
        "evaluations": optimizer.evaluations,
        "best_fitness_um": best_fitness,
        "best_params": config.parameters(config.from_unit(best_unit)),
        "elapsed_s": elapsed,
    }
    partial = out_dir / "progress.json.partial"
    partial.write_text(json.dumps(progress, indent=2) + "\n")
    partial.replace(out_dir / "progress.json")


def write_result(out_dir: Path, result: dict[str, Any]) -> None:
    """Write ``result.json``."""
    (out_dir / "result.json").write_text(json.dumps(result, indent=2) + "\n")


def logged_fitness(out_dir: Path) -> tuple[np.ndarray, list[str]]:
    """Fitness (um) and status of each evaluation the optimizer was told, in log order.

    A candidate that early stopping runs in a second pass of its generation (stopped in the
    first) is logged twice: it counts once, with its final result, where it first appears.
    """
    log = EvaluationLog(Path(out_dir) / "evaluations.jsonl")
    entries = log.entries
    log.close()
    final: dict[tuple[str, Any], dict[str, Any]] = {}  # keeps each first place
    for entry in entries:
        final[(entry["key"], entry.get("generation"))] = entry
    told = list(final.values())
    return np.array([e["fitness"] for e in told], dtype=float), [e["status"] for e in told]


LOG_KEYS = frozenset({"key", "x", "fitness"})


def candidate_key(x: np.ndarray) -> str:
    """Exact identity of a candidate: the hex of its float64 bytes."""
    return np.ascontiguousarray(x, dtype=np.float64).tobytes().hex()


class EvaluationLog:
    """Evaluations of one campaign on disk (``evaluations.jsonl``) and in memory: the
    append-only log that is also the campaign's checkpoint.

    Each completed evaluation is appended as one JSON line and flushed to the operating system
    at once, so a process that dies, even by ``kill -9`` in the middle of a generation, loses no
    completed evaluation; the campaign syncs the file to disk (fsync) after every generation, so
    a crash of the machine itself loses at most the generation under way. A campaign resumes by
    replaying its optimizer from the seed: every batch the optimizer asks for again is answered
    from this log, keyed by the exact bits of the candidate, and only what is missing is
    computed. A torn last line (the write that was cut off) is ignored.

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
        for number, entry in json_lines(
            complete,
            lambda number, exc: (
                f"{self.path}: line {number}: corrupt line in the evaluation log: {exc}"
            ),
        ):
            missing = LOG_KEYS - set(entry) if isinstance(entry, dict) else LOG_KEYS
            if missing:
                raise ValueError(
                    f"{self.path}: line {number}: not an evaluation (expected a JSON object with "
                    f"{sorted(LOG_KEYS)}; missing {sorted(missing)})"
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


class FolderLockedError(CampaignError):
    """Another running process writes to the folder."""


class FolderLock:
    """Exclusive lock of a campaign folder: ``campaign.lock`` holds the writer's pid while it
    runs.

    The lock is an exclusive ``flock`` on the file, which the kernel releases when its process
    ends in any way (even ``kill -9``); the pid inside names the holder in the refusal. A lock
    file whose pid is no longer running is stale and taken over; one whose pid still runs is
    refused even when the file system does not enforce ``flock``.

    Parameters
    ----------
    folder
        The campaign folder (must exist).
    """

    def __init__(self, folder: Path) -> None:
        self.path = Path(folder) / LOCK_NAME
        self._fd: int | None = None

    def _holder(self) -> str:
        try:
            return self.path.read_text().strip() or "unknown"
        except OSError:
            return "unknown"

    def acquire(self) -> None:
        """Take the lock at once or raise :class:`FolderLockedError` naming its holder."""
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise FolderLockedError(
                    f"{self.path.parent}: in use by process {self._holder()} (lock file "
                    f"{self.path}); wait for it to end or use another --out"
                ) from None
            try:
                same_file = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same_file = False
            if same_file:
                break
            os.close(fd)  # the holder removed the file meanwhile: lock the new one
        stale = os.read(fd, 64).decode(errors="replace").strip()
        if stale.isdigit() and int(stale) != os.getpid() and pid_alive(int(stale)):
            os.close(fd)  # a file system without working flock, and the holder still runs
            raise FolderLockedError(
                f"{self.path.parent}: in use by process {stale} (lock file {self.path}); if that "
                "process is not a campaign, delete the lock file"
            )
        if stale:
            LOG.warning("%s: stale lock of process %s (not running) taken over", self.path, stale)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd = fd

    def release(self) -> None:
        """Remove the lock file and release the lock."""
        if self._fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> FolderLock:
        self.acquire()
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()
