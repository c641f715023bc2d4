"""Versions of the software a result depends on, for the provenance of what a command writes."""

from __future__ import annotations

import functools
import os
import platform
import re
import sys

PACKAGES = ("twin-cosim", "fmpy", "numpy", "scipy", "numba", "pandas", "control")


def _normalized(name: str) -> str:
    """A distribution's name as its ``.dist-info`` folder spells it (PEP 503, lower case)."""
    return re.sub(r"[-_.]+", "_", name).lower()


@functools.cache
def _dist_info_versions() -> dict[str, str]:
    """Version of every distribution with a ``NAME-VERSION.dist-info`` folder on ``sys.path``
    (the first found wins, as for an import)."""
    found: dict[str, str] = {}
    for folder in sys.path:
        try:
            entries = os.scandir(folder or ".")
        except OSError:
            continue
        with entries:
            for entry in entries:
                if entry.name.endswith(".dist-info") and "-" in entry.name:
                    name, version = entry.name[: -len(".dist-info")].split("-", 1)
                    found.setdefault(_normalized(name), version)
    return found


def installed_version(distribution: str) -> str | None:
    """The installed version of ``distribution``, None when it is not installed.

    Read off the names of the ``.dist-info`` folders on ``sys.path`` (a millisecond), with
    ``importlib.metadata`` (a twentieth of a second to import) only for a distribution without one.
    """
    version = _dist_info_versions().get(_normalized(distribution))
    if version is not None:
        return version
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as metadata_version

    try:
        return metadata_version(distribution)
    except PackageNotFoundError:
        return None


def versions() -> dict[str, str]:
    """Python's version and each of :data:`PACKAGES`' ("not installed" when it is not)."""
    found = {"python": platform.python_version()}
    for package in PACKAGES:
        found[package] = installed_version(package) or "not installed"
    return found
