"""The compiled loops built ahead of time into one shared library, loaded without numba.

numba's ahead-of-time compiler (``numba.pycc``) compiles the functions of
:mod:`twin_cosim.loops.kernels` for the signatures below into an extension module in the per-user
cache (``loops/<fingerprint>/``, beside the built FMUs), keyed by a fingerprint of the sources the
loops are made from and the versions of Python, numpy, numba and llvmlite. A process that finds
the library for its sources imports it in about a millisecond, instead of importing numba and
readying its compiler target (about half a second) to load the cached machine code of the
just-in-time path. Built by ``twin build``; without it (or after a source changed) the loops
compile just in time, with the same results. :func:`compiled_loops` is how a process gets the
master: this library when it is built, else the just-in-time one.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import os
import sys
import tempfile
import warnings
from pathlib import Path
from types import ModuleType

import numpy as np

from fmu_build.build import cache_dir
from twin_cosim.versions import installed_version

MODULE = "twin_loops"
_PACKAGE = Path(__file__).resolve().parents[1]
# What the loops are made from: their code and the statuses they compile in (loops/__init__.py),
# the controller they inline, the plant contract (the positions of inputs and outputs), and this
# file's signatures.
SOURCES = (
    _PACKAGE / "loops" / "kernels.py",
    _PACKAGE / "loops" / "__init__.py",
    _PACKAGE / "loops" / "ahead.py",
    _PACKAGE / "controller.py",
    _PACKAGE / "plant.py",
)
# The one signature of the master (:func:`twin_cosim.loops.kernels.master`): per-axis integers
# and rows, every option an array that is empty when off.
_INTEGERS = "i8[::1]"
_ROWS = "f8[:, ::1]"
SIGNATURES = {
    "master": (
        f"UniTuple(i8, 3)({_INTEGERS}, {_INTEGERS}, {_INTEGERS}, {_INTEGERS}, {_INTEGERS}, "
        f"u4[:, ::1], "
        f"u4[:, ::1], {_ROWS}, {_ROWS}, f8, i8, {_ROWS}, {_ROWS}, {_ROWS}, {_ROWS}, {_ROWS}, "
        f"{_ROWS}, {_ROWS}, {_ROWS}, f8, f8[:, :, ::1], f8[:, :, ::1])"
    ),
}


_LOADED: list[ModuleType] = []


def compiled_loops() -> ModuleType:
    """The compiled master of this process: the library built ahead when there is one for these
    sources, else :mod:`twin_cosim.loops.kernels` (numba, just in time); chosen once."""
    if not _LOADED:
        library = load()
        if library is None:
            from twin_cosim.loops import kernels

            library = kernels
        _LOADED.append(library)
    return _LOADED[0]


def ready_compiled_loops() -> None:
    """Load the compiled loops now, as the first run would: a process about to run (a pool's
    worker while its parent prepares) calls this ahead. On the just-in-time path this also
    readies numba's compiler target, most of the cost (about 0.3 s) of loading cached code."""
    loops = compiled_loops()
    if loops.__name__ == "twin_cosim.loops.kernels":
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()


class LoopBuildError(RuntimeError):
    """Compiling the loops ahead failed; the message says why."""


def fingerprint() -> str:
    """SHA-256 (first 16 hex digits) over the loops' sources, the Python ABI and the versions of
    numpy, numba and llvmlite."""
    digest = hashlib.sha256()
    for source in SOURCES:
        digest.update(source.read_bytes())
    versions = [installed_version(package) or "" for package in ("numba", "llvmlite")]
    for part in (sys.implementation.cache_tag, np.__version__, *versions):
        digest.update(part.encode())
    return digest.hexdigest()[:16]


def library_path() -> Path:
    """Where the library for these sources is (or would be) in the per-user cache."""
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    return cache_dir() / "loops" / fingerprint() / f"{MODULE}{suffix}"


def load() -> ModuleType | None:
    """The library built for these sources, imported; None when it is not built.

    Raises
    ------
    LoopBuildError
        The file is there but does not import (a truncated or foreign file): ``twin build
        --force`` rebuilds it.
    """
    path = library_path()
    if not path.is_file():
        return None
    spec = importlib.util.spec_from_file_location(MODULE, path)
    if spec is None or spec.loader is None:
        raise LoopBuildError(f"{path}: not an extension module")
    try:
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except ImportError as error:
        raise LoopBuildError(
            f"{path}: the compiled loops do not load ({error}); rebuild with `twin build --force`"
        ) from error
    return module


def build(force: bool = False) -> Path:
    """Compile the loops ahead into the per-user cache (unless there already); the library's
    path. Takes about half a minute; the file appears complete or not at all."""
    path = library_path()
    if path.is_file() and not force:
        return path
    with warnings.catch_warnings():  # pending deprecation since numba 0.57; see docs/speed.md
        warnings.simplefilter("ignore")
        from numba.pycc import CC

    from twin_cosim.loops import kernels

    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".build-", dir=path.parent) as folder:
        compiler = CC(MODULE)
        compiler.output_dir = folder
        compiler.verbose = False
        for name, signature in SIGNATURES.items():
            compiler.export(name, signature)(getattr(kernels, name).py_func)
        try:
            compiler.compile()
        except Exception as error:  # the toolchain's own errors, of many kinds
            raise LoopBuildError(f"compiling the loops ahead failed: {error}") from error
        produced = Path(folder) / path.name
        if not produced.is_file():
            raise LoopBuildError(f"compiling the loops ahead wrote no {path.name} in {folder}")
        os.replace(produced, path)
    return path
