"""Scenario runs on a worker pool (:mod:`twin_cosim.workers`): their records, for tables and
figures.

Light to import: the parent of a pool builds the tasks and never runs the plant; the plant and
the compiled loop are loaded in the workers (:class:`RecordRuns`), which start with
:func:`prepare_worker`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

    from twin_cosim.controller import TunedParameters
    from twin_cosim.scenario import Scenario
    from twin_cosim.workers import ProcessPool, SerialPool

RunTask = tuple["Scenario", "TunedParameters | None"]  # a scenario and a set (None: its own)


def prepare_worker(modules: tuple[str, ...] = ()) -> None:
    """What a pool's process does as it starts, before its first task: import the co-simulation
    (numpy, fmpy; pandas only where a task asks for a DataFrame), load the compiled loops and
    import ``modules`` (those of its workers), while the parent prepares.

    A pool of campaign or diagnosis workers takes :func:`prepare_campaign_worker` or
    :func:`prepare_replay_worker`.
    """
    from twin_cosim.loops import ready_compiled_loops  # what this process is for

    ready_compiled_loops()
    for module in ("twin_cosim.cosim", *modules):
        importlib.import_module(module)


def prepare_campaign_worker() -> None:
    """:func:`prepare_worker` of a campaign's pool: the objective's modules too."""
    prepare_worker(("twin_cosim.optimize.objective",))


def prepare_replay_worker() -> None:
    """:func:`prepare_worker` of a diagnosis's pool: the replays and fits (SciPy's optimizers)."""
    prepare_worker(("twin_cosim.gap.which.replay",))


@dataclass(frozen=True)
class RecordSpec:
    """The recipe of a :class:`RecordRuns` worker: the FMU its plant loads."""

    fmu: str

    def build(self) -> RecordRuns:
        """The worker, in the process that runs it."""
        return RecordRuns(self.fmu)


class RecordRuns:
    """A worker running (scenario, parameter set) tasks on one plant; it answers their records
    (:func:`twin_cosim.cosim.run_scenario`)."""

    def __init__(self, fmu: str) -> None:
        from twin_cosim.cosim import run_scenario  # the run's modules: in the workers only
        from twin_cosim.plant import Plant

        self.plant = Plant(fmu)
        self.run = run_scenario

    def __call__(self, task: RunTask) -> pd.DataFrame:
        """The record of the scenario run with the set (None: the scenario's own)."""
        scenario, tuned = task
        return self.run(self.plant, scenario, tuned)

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def run_records(
    pool: SerialPool | ProcessPool, fmu: Path, tasks: list[RunTask]
) -> list[pd.DataFrame]:
    """The records of ``tasks`` run on ``fmu`` by the pool's workers, in task order."""
    found = dict(pool.imap(tasks, RecordSpec(str(fmu))))
    return [found[i] for i in range(len(tasks))]


@dataclass(frozen=True)
class AutotuneSpec:
    """The recipe of an :class:`AutotuneRuns` worker: the FMU its plant loads."""

    fmu: str

    def build(self) -> AutotuneRuns:
        """The worker, in the process that runs it."""
        return AutotuneRuns(self.fmu)


class AutotuneRuns:
    """A worker answering the auto-tuner's proposal for a scenario, from the twin's plant FRF
    measured on its plant (:func:`twin_cosim.frequency.tuning.propose`)."""

    def __init__(self, fmu: str) -> None:
        from twin_cosim.frequency.tuning import propose  # in the workers only
        from twin_cosim.plant import Plant

        self.plant = Plant(fmu)
        self.propose = propose

    def __call__(self, scenario: Scenario) -> dict[str, Any]:
        """The proposal's summary (``twin autotune``'s layout)."""
        proposal, _ = self.propose(self.plant, scenario)
        return proposal.summary()

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def autotune_summary(
    pool: SerialPool | ProcessPool, fmu: Path, scenario: Scenario
) -> dict[str, Any]:
    """The auto-tuner's proposal for ``scenario`` on ``fmu``, made by a worker of the pool."""
    [(_, summary)] = pool.imap([scenario], AutotuneSpec(str(fmu)))
    return summary
