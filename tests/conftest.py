"""Shared fixtures: the project's FMU (built once per session), open-loop stepping, the CLI, the
last figure a test saved; Ctrl-C as a terminal delivers it, also in a suite started in the
background."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pytest

from fmu_build.build import build_fmu
from twin_cosim.plant import Plant

ROOT = Path(__file__).resolve().parents[1]


def pytest_configure(config: pytest.Config) -> None:
    """A shell starts a background job (``pytest ... &``) with SIGINT ignored, and its children
    inherit that: the tests of what Ctrl-C does would then see nothing happen. Handle SIGINT as
    an interactive Python does (KeyboardInterrupt), which the processes the tests start inherit
    as the default action."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session")
def twin_cli() -> Callable[..., subprocess.CompletedProcess]:
    """Run ``python -m twin_cosim ARGS...`` from the repository root, as a user would."""

    def run(*args: str) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "twin_cosim", *args]
        return subprocess.run(command, capture_output=True, text=True, cwd=ROOT)

    return run


@pytest.fixture(scope="session")
def fmu_path() -> Path:
    """The drive2mass FMU, built from source if missing or stale."""
    return build_fmu("drive2mass")


@pytest.fixture()
def plant(fmu_path: Path):
    """A fresh drive2mass plant, freed after the test."""
    with Plant(fmu_path) as instance:
        yield instance


OpenLoop = Callable[..., dict[str, np.ndarray]]


@pytest.fixture()
def open_loop(plant: Plant) -> OpenLoop:
    """Step the plant in open loop with a given current sequence.

    Returns a function ``run(current, h, parameters, outputs, disturbance=None)`` giving a dict
    of output arrays sampled after every step (plus ``t``, the end time of each step, s).
    """

    def run(
        current: np.ndarray,
        h: float,
        parameters: Mapping[str, float],
        outputs: tuple[str, ...],
        disturbance: np.ndarray | None = None,
    ) -> dict[str, np.ndarray]:
        plant.start_run(parameters)
        fmu = plant.fmu
        vr_in = [plant.value_reference("current_cmd"), plant.value_reference("disturbance_torque")]
        vr_out = [plant.value_reference(n) for n in outputs]
        dist = np.zeros(len(current)) if disturbance is None else disturbance
        values = np.empty((len(current), len(outputs)))
        for k, (u, d) in enumerate(zip(current, dist, strict=True)):
            fmu.setReal(vr_in, [float(u), float(d)])
            fmu.doStep(k * h, h)
            values[k] = fmu.getReal(vr_out)
        result = {name: values[:, i] for i, name in enumerate(outputs)}
        result["t"] = (np.arange(len(current)) + 1) * h
        return result

    return run


@pytest.fixture()
def saved_figure(monkeypatch) -> dict:
    """``{"fig": ...}``: the last matplotlib figure saved during the test (drawn as usual)."""
    from matplotlib.figure import Figure

    saved = {}
    original = Figure.savefig

    def keep(fig, *args, **kwargs):
        saved["fig"] = fig
        return original(fig, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved
