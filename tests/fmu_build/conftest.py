"""The plant FMUs of the project, for the tests that every FMU must pass: each model in FMI 2.0
(``model_fmu``) and each model in each FMI version (``any_fmu``)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import pytest

from fmu_build.build import FMI_VERSIONS, build_fmu

MODELS = ("drive2mass", "emps", "hsm150")


class BuiltFmu(NamedTuple):
    model: str
    fmi_version: int
    path: Path


@pytest.fixture(scope="session", params=MODELS)
def model_fmu(request) -> tuple[str, Path]:
    """(model name, .fmu path) of the FMI 2.0 FMU, built from source if missing or stale."""
    return request.param, build_fmu(request.param)


@pytest.fixture(
    scope="session",
    params=[(m, v) for m in MODELS for v in FMI_VERSIONS],
    ids=lambda p: f"{p[0]}-fmi{p[1]}",
)
def any_fmu(request) -> BuiltFmu:
    """Each model's FMU in each FMI version, built from source if missing or stale."""
    model, version = request.param
    return BuiltFmu(model, version, build_fmu(model, fmi_version=version))
