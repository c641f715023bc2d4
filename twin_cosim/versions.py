"""Versions of the software a result depends on, for the provenance of what a command writes."""

from __future__ import annotations

import platform
from importlib.metadata import PackageNotFoundError, version

PACKAGES = ("twin-cosim", "fmpy", "numpy", "scipy", "numba", "pandas", "control")


def versions() -> dict[str, str]:
    """Python's version and each of :data:`PACKAGES`' ("not installed" when it is not)."""
    found = {"python": platform.python_version()}
    for package in PACKAGES:
        try:
            found[package] = version(package)
        except PackageNotFoundError:
            found[package] = "not installed"
    return found
