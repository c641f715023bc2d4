"""Where the tests find the EMPS benchmark's estimation run, and a mark for tests that need it.

In the folder of ``TWIN_COSIM_DATA`` when set, else in ``../shared/data/emps`` beside the
repository; tests that need it skip cleanly where it is absent (it is never part of the project).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from twin_cosim.environment import DATA_ENV

ROOT = Path(__file__).resolve().parents[1]
EMPS_DATA = (
    Path(os.environ[DATA_ENV]) if os.environ.get(DATA_ENV) else ROOT.parent / "shared/data/emps"
) / "DATA_EMPS.mat"
needs_emps_data = pytest.mark.skipif(
    not EMPS_DATA.exists(), reason=f"EMPS data not found at {EMPS_DATA}"
)
