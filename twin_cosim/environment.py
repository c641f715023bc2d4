"""Environment variables that ``twin`` reads (light to import: the command line names them).

- ``TWIN_COSIM_DATA``: the folder of measured data files (e.g. the EMPS benchmark's
  DATA_EMPS.mat); set by ``--data DIR``, read by :mod:`twin_cosim.scenario`.
- ``TWIN_COSIM_CACHE``: the folder of built FMUs (:data:`fmu_build.build.CACHE_ENV`).
"""

from __future__ import annotations

DATA_ENV = "TWIN_COSIM_DATA"
