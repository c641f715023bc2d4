"""The plant's FMU is extracted once into the per-user cache, by content, and shared."""

from __future__ import annotations

import shutil
from pathlib import Path

from fmu_build.build import CACHE_ENV
from twin_cosim.plant import Plant, extracted_fmu


def test_plants_of_one_fmu_share_one_extraction_that_outlives_them(fmu_path, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    with Plant(fmu_path) as first, Plant(fmu_path) as second:
        assert first._unzip_dir == second._unzip_dir
    (folder,) = (tmp_path / "cache" / "extracted").iterdir()
    assert (folder / "modelDescription.xml").is_file()
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]  # no partial folder left
    assert extracted_fmu(fmu_path) == folder


def test_another_fmu_content_is_extracted_apart(fmu_path, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    copy = tmp_path / "copy" / fmu_path.name
    copy.parent.mkdir()
    shutil.copy(fmu_path, copy)
    assert extracted_fmu(copy) == extracted_fmu(fmu_path)  # same content, same folder
    with copy.open("ab") as archive:
        archive.write(b"\0")  # a zip with trailing bytes still reads: another content
    assert extracted_fmu(copy) != extracted_fmu(fmu_path)
    assert len(list(Path(tmp_path / "cache" / "extracted").iterdir())) == 2
