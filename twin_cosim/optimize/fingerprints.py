"""Content fingerprints of what decides a campaign's results: scenario, plant FMU, settings.

A campaign stores them in ``campaign.json``; a resume whose inputs do not give the same
fingerprints is refused, so a log never mixes evaluations of two different problems. Paths do
not count, contents do: a scenario moved to another folder still resumes, an edited one does not.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path
from typing import Any

from twin_cosim.scenario import Scenario


def _digest(*parts: bytes) -> str:
    hasher = hashlib.sha256()
    for part in parts:
        hasher.update(hashlib.sha256(part).digest())
    return hasher.hexdigest()


def scenario_fingerprint(scenario: Scenario) -> str:
    """The scenario file's bytes plus the reference and disturbance they resolve to.

    The resolved arrays cover what the file only names (a reference CSV, a measured run).
    """
    disturbance = b"" if scenario.disturbance is None else scenario.disturbance.tobytes()
    return _digest(
        Path(scenario.source).read_bytes(), scenario.reference.position.tobytes(), disturbance
    )


def fmu_fingerprint(fmu: Path) -> str:
    """The FMU's member names and contents (not the archive's timestamps)."""
    with zipfile.ZipFile(fmu) as archive:
        names = sorted(info.filename for info in archive.infolist() if not info.is_dir())
        return _digest(*(part for name in names for part in (name.encode(), archive.read(name))))


def settings_fingerprint(settings: dict[str, Any]) -> str:
    """Method, seed, budget, method settings and the checked ``optimize`` section."""
    return _digest(json.dumps(settings, sort_keys=True, default=str).encode())
