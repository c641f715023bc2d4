"""Scenario runs on a worker pool (:mod:`twin_cosim.workers`): their records, for tables and
figures.

Light to import: the parent of a pool builds the tasks and never runs the plant; the plant and
the compiled master are loaded in the workers (:class:`PlantTasks`), which start with
:func:`prepare_worker`.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable

    from twin_cosim.controller import TunedParameters
    from twin_cosim.plant import Plant
    from twin_cosim.run_record import RunRecord
    from twin_cosim.scenario import Scenario
    from twin_cosim.workers import ProcessPool, SerialPool

RunTask = tuple["Scenario", "TunedParameters | None"]  # a scenario and a set (None: its own)


def prepare_worker(modules: tuple[str, ...] = ()) -> None:
    """What a pool's process does as it starts, before its first task: import the co-simulation
    (numpy, fmpy), load the compiled master and import ``modules`` (those of its workers), while
    the parent prepares.

    A pool of campaign or diagnosis workers takes :func:`prepare_campaign_worker` or
    :func:`prepare_replay_worker`.
    """
    from twin_cosim.loops.ahead import ready_compiled_loops  # what this process is for

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
class PlantTasksSpec:
    """The recipe of a :class:`PlantTasks` worker: the FMU its plant loads, and what it answers
    for a task (a module-level function of the plant and the task, sent by reference)."""

    fmu: str
    answer: Callable[[Plant, Any], Any]

    def build(self) -> PlantTasks:
        """The worker, in the process that runs it."""
        return PlantTasks(self.fmu, self.answer)


class PlantTasks:
    """A worker answering tasks on one plant of its own."""

    def __init__(self, fmu: str, answer: Callable[[Plant, Any], Any]) -> None:
        from twin_cosim.plant import Plant  # the run's modules: in the workers only

        self.plant = Plant(fmu)
        self.answer = answer

    def __call__(self, task: Any) -> Any:
        """What the worker answers for ``task``."""
        return self.answer(self.plant, task)

    def close(self) -> None:
        """Free the plant."""
        self.plant.close()


def scenario_record(plant: Plant, task: RunTask) -> RunRecord:
    """The record of a scenario run with a set (None: the scenario's own)
    (:func:`twin_cosim.cosim.run_scenario`)."""
    from twin_cosim.cosim import run_scenario  # in the workers only

    scenario, tuned = task
    return run_scenario(plant, scenario, tuned)


def autotune_proposal(plant: Plant, scenario: Scenario) -> dict[str, Any]:
    """The auto-tuner's proposal for a scenario from the twin's plant FRF measured on ``plant``
    (:func:`twin_cosim.frequency.autotune.propose`; ``twin autotune``'s layout)."""
    from twin_cosim.frequency.autotune import propose  # in the workers only

    proposal, _ = propose(plant, scenario)
    return proposal.summary()


def run_records(pool: SerialPool | ProcessPool, fmu: Path, tasks: list[RunTask]) -> list[RunRecord]:
    """The records of ``tasks`` run on ``fmu`` by the pool's workers, in task order."""
    found = dict(pool.imap(tasks, PlantTasksSpec(str(fmu), scenario_record)))
    return [found[i] for i in range(len(tasks))]


def autotune_summary(
    pool: SerialPool | ProcessPool, fmu: Path, scenario: Scenario
) -> dict[str, Any]:
    """The auto-tuner's proposal for ``scenario`` on ``fmu``, made by a worker of the pool."""
    [(_, summary)] = pool.imap([scenario], PlantTasksSpec(str(fmu), autotune_proposal))
    return summary
