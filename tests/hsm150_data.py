"""Where the tests find the HSM150 bench's runs, and a mark for tests that need them.

In the folder of ``TWIN_COSIM_DATA`` when it holds them, else in ``../shared/data/hsm150`` beside
the repository; tests that need them skip cleanly where they are absent (they are never part of
the project).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from twin_cosim.environment import DATA_ENV

ROOT = Path(__file__).resolve().parents[1]
RUNS = [f"idf_{d}_{k}.mat" for d in ("pos_0.06", "neg_0.04") for k in (1, 2, 3)]
_FOLDERS = ([Path(os.environ[DATA_ENV])] if os.environ.get(DATA_ENV) else []) + [
    ROOT.parent / "shared/data/hsm150"
]
HSM150_DATA = next((f for f in _FOLDERS if (f / RUNS[0]).exists()), _FOLDERS[-1])
needs_hsm150_data = pytest.mark.skipif(
    not all((HSM150_DATA / run).exists() for run in RUNS),
    reason=f"HSM150 runs not found in {HSM150_DATA}",
)
