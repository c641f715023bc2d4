"""The wheel's configuration: every Python package, every C source and every scenario ships."""

from __future__ import annotations

import fnmatch
from pathlib import Path

import pytest
from setuptools import find_packages

tomllib = pytest.importorskip("tomllib")

ROOT = Path(__file__).resolve().parents[1]
CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
MAPPED = {"fmu_build.models": "models", "twin_cosim.scenarios": "scenarios"}


def test_folders_are_mapped_into_the_packages():
    assert CONFIG["package-dir"] == MAPPED


def test_every_package_and_model_folder_is_listed():
    code = set(find_packages(where=str(ROOT), include=["twin_cosim*", "fmu_build*"]))
    models = {f"fmu_build.models.{p.name}" for p in (ROOT / "models").iterdir() if p.is_dir()}
    assert set(CONFIG["packages"]) == code | models | set(MAPPED)


def test_every_source_file_is_package_data():
    data = CONFIG["package-data"]
    for package, folder in MAPPED.items():
        for path in (ROOT / folder).rglob("*"):
            if path.is_dir() or "__pycache__" in path.parts:
                continue
            relative = path.relative_to(ROOT / folder)
            owner = ".".join([package, *relative.parent.parts])
            assert any(fnmatch.fnmatch(path.name, p) for p in data.get(owner, [])), relative
