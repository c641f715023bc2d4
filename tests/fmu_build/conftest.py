"""Both plant FMUs of the project, for the tests that every FMU must pass."""

from __future__ import annotations

from pathlib import Path

import pytest

from fmu_build.build import build_fmu

MODELS = ("drive2mass", "emps")


@pytest.fixture(scope="session", params=MODELS)
def model_fmu(request) -> tuple[str, Path]:
    """(model name, .fmu path), built from source if missing or stale."""
    return request.param, build_fmu(request.param)
