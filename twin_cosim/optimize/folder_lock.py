"""One writer per campaign folder: ``campaign.lock`` holds the writer's pid while it runs.

The lock is an exclusive ``flock`` on the file, which the kernel releases when its process ends
in any way (even ``kill -9``); the pid inside names the holder in the refusal. A lock file whose
pid is no longer running is stale and taken over; one whose pid still runs is refused even when
the file system does not enforce ``flock``.
"""

from __future__ import annotations

import fcntl
import logging
import os
from pathlib import Path

from twin_cosim.workers import pid_alive

LOG = logging.getLogger(__name__)
LOCK_NAME = "campaign.lock"


class FolderLockedError(ValueError):
    """Another running process writes to the folder."""


class FolderLock:
    """Exclusive lock of a campaign folder, held from ``__enter__`` to ``__exit__``.

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
