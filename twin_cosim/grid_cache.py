"""Interpolated references kept across runs, in the per-user cache.

A reference's position-loop grid (:func:`twin_cosim.reference.interpolate`) is stored under a
digest of everything it is made from: the reference samples and periods, the interpolating code
and the versions of SciPy and numpy. A run of an unchanged reference reads it back (the same
bits) instead of importing SciPy and fitting the spline again. Each file is written under a
temporary name and renamed into place, so concurrent runs never read a partial one.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from fmu_build.build import cache_dir
from twin_cosim.versions import installed_version


def grid_key(samples: np.ndarray, sample_period: float, loop_period: float, code: Path) -> str:
    """The digest of a grid's inputs: samples (m), periods (s), the source file ``code`` of the
    interpolation and the versions of SciPy and numpy."""
    digest = hashlib.sha256(np.ascontiguousarray(samples, dtype=np.float64).tobytes())
    versions = (installed_version("scipy") or "", installed_version("numpy") or "")
    for part in (repr(sample_period), repr(loop_period), *versions):
        digest.update(part.encode())
    digest.update(code.read_bytes())
    return digest.hexdigest()[:32]


def _path(key: str) -> Path:
    return cache_dir() / "references" / f"{key}.npy"


def load_grid(key: str) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The stored position (m), velocity (m/s) and acceleration (m/s^2) of ``key``, or None."""
    try:
        stored = np.load(_path(key))
    except (OSError, ValueError):  # not stored yet, or unreadable: interpolate again
        return None
    position, velocity, acceleration = (np.array(row) for row in stored)
    return position, velocity, acceleration


def store_grid(
    key: str, position: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray
) -> None:
    """Store a grid under ``key`` (atomically)."""
    path = _path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as file:
            np.save(file, np.stack([position, velocity, acceleration]))
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
