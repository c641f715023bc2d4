"""A fresh plant of each project model, for the tests that every model's slave must pass."""

from __future__ import annotations

import pytest

from fmu_build.build import build_fmu
from twin_cosim.plant import Plant


@pytest.fixture(params=("drive2mass", "emps"))
def any_plant(request):
    """A plant of each model in turn, freed after the test."""
    with Plant(build_fmu(request.param), request.param) as instance:
        yield instance
