"""The ask/tell loop of a campaign: every generation answered from the log or the evaluator.

The optimizer starts from the scenario's parameters (the Fine-Tune set by default) when they lie
inside the bounds. Resuming replays the optimizer from its seed, answering from the log every
batch already evaluated, so a resumed campaign ends exactly where an uninterrupted one would.

Early stopping (CE, on by default where exact, see :mod:`twin_cosim.optimize.early_stop`): a
generation's candidates go out one at a time, ``ahead`` of the evaluator more at a time than
there are workers (on a local process pool one: a worker that finishes finds its next candidate
waiting), each with the cutoff known when it goes and its generation's key, by which the worker
lowers that cutoff with its own complete evaluations of the generation; a stopped candidate's
lower bound is reused from the log only within its own generation (elsewhere it is evaluated
again). Without early stopping a generation goes out at once.
"""

from __future__ import annotations

import logging
import math
import secrets
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from tqdm import tqdm

from twin_cosim.optimize.algorithms.base import Optimizer
from twin_cosim.optimize.campaign_folder import write_progress
from twin_cosim.optimize.campaign_spec import CampaignError
from twin_cosim.optimize.config import OptimizeConfig
from twin_cosim.optimize.early_stop import (
    elite_count,
    elite_cutoff,
    guess_above,
    guess_after_miss,
)
from twin_cosim.optimize.evaluation_log import EvaluationLog, candidate_key
from twin_cosim.optimize.evaluation_order import likeliest_best_first
from twin_cosim.optimize.evaluator_protocol import Evaluator, SchedulerError
from twin_cosim.optimize.methods import method_label
from twin_cosim.optimize.worker_specs import EvaluationTask

LOG = logging.getLogger(__name__)


class AskTellLoop:
    """Asks the optimizer for generations, answers each from the log or the evaluator, tells it.

    Parameters
    ----------
    optimizer
        The optimizer, in the unit cube.
    config
        The objective's configuration (bounds: unit cube <-> physical units).
    log
        The campaign's evaluation log: read for answers, appended with every new result.
    evaluator
        Scores the candidates the log cannot answer.
    early_stop
        Send candidates one at a time, ``evaluator.workers + evaluator.ahead`` out at a time,
        each with the cutoff known then.
    bar
        Progress bar (evaluations).
    """

    def __init__(
        self,
        optimizer: Optimizer,
        config: OptimizeConfig,
        log: EvaluationLog,
        evaluator: Evaluator,
        early_stop: bool,
        bar: tqdm,
    ) -> None:
        self.optimizer = optimizer
        self.config = config
        self.log = log
        self.evaluator = evaluator
        self.early_stop = early_stop
        self.bar = bar
        self.logged_before = {entry["key"] for entry in log.entries}
        self.reused = 0  # answers from entries logged before this run
        self.guess = math.inf  # the guess of the next generation's cutoff (um)
        self.key = secrets.token_hex(8)  # with the generation's number: its key for the workers

    def run(self, out_dir: Path, start: float) -> None:
        """Ask and tell until the optimizer stops; the log synced to disk and ``progress.json``
        written after every generation.

        ``start`` is the loop's start (``time.perf_counter()``, s).
        """
        optimizer = self.optimizer
        while optimizer.stop_reason is None:
            unit = optimizer.ask()
            if len(unit) == 0:
                break
            optimizer.tell(self._generation(self.config.from_unit(unit)))
            self.log.sync()
            write_progress(out_dir, optimizer, self.config, time.perf_counter() - start)
            self.bar.set_postfix(gen=optimizer.generation, best_um=f"{optimizer.best[1]:.3f}")

    def _generation(self, candidates: np.ndarray) -> np.ndarray:
        """The fitness (um) of every candidate of a generation (physical units, one per row).

        With early stopping, each candidate goes out with the cutoff known then, lowered to the
        guess from the previous generation; once every candidate is answered, those stopped
        below the generation's cutoff (where the guess was too low) run again with the cutoff
        known then, lowered to a second guess (a third pass has none).
        """
        fitness = np.empty(len(candidates))
        bound = np.zeros(len(candidates), dtype=bool)  # a stopped candidate's lower bound
        missing = self._answer_from_log(candidates, fitness, bound)
        known = [i for i in range(len(candidates)) if i not in missing]
        guess = self.guess
        again = False  # candidates answered before (counted by the progress bar) run again
        while True:
            if missing:
                self._evaluate(candidates, missing, fitness, bound, known, guess, again)
            cutoff = self._cutoff(fitness, bound, known)
            missing = [i for i in range(len(candidates)) if bound[i] and fitness[i] <= cutoff]
            if not missing:
                break
            known = [i for i in known if i not in missing]
            guess = math.inf if again else guess_after_miss(guess)
            again = True
        self.guess = guess_above(cutoff)
        return fitness

    def _cutoff(self, fitness: np.ndarray, bound: np.ndarray, known: list[int]) -> float:
        """The generation's cutoff from the values known (um; inf without early stopping):
        from the complete evaluations only (a lower bound is no value)."""
        if not self.early_stop:
            return math.inf
        complete = [i for i in known if not bound[i]]
        return elite_cutoff(self.optimizer, len(fitness), fitness[complete])

    def _evaluate(
        self,
        candidates: np.ndarray,
        rows: list[int],
        fitness: np.ndarray,
        bound: np.ndarray,
        known: list[int],
        guess: float,
        again: bool,
    ) -> None:
        """Evaluate ``rows`` of ``candidates`` (duplicates once), ``ahead`` more out at a time
        than there are workers, each with the cutoff known when it goes out, at most ``guess`` (um),
        and the generation's key and elite count (by which a worker lowers the cutoff with its
        own complete evaluations of the generation); log them and fill their
        ``fitness`` and ``bound`` (stopped) and the ``known`` rows. Rows evaluated ``again``
        are not counted by the progress bar a second time."""
        unique: dict[str, list[int]] = {}
        for i in rows:
            unique.setdefault(candidate_key(candidates[i]), []).append(i)
        firsts = [same[0] for same in unique.values()]
        if self.early_stop:  # the cost only: the generation's best known sooner
            firsts = [firsts[k] for k in self._likeliest_best_first(candidates[firsts])]

        generation = f"{self.key}:{self.optimizer.generation}"
        elite = elite_count(self.optimizer, len(candidates)) if self.early_stop else 0

        def tasks() -> Iterator[EvaluationTask]:
            for i in firsts:
                cutoff = min(self._cutoff(fitness, bound, known), guess)
                yield EvaluationTask(candidates[i], cutoff, generation, elite)

        in_flight = self.evaluator.workers + self.evaluator.ahead if self.early_stop else None
        for j, result in self.evaluator.imap(tasks(), in_flight):
            entry = self.log.append(candidates[firsts[j]], result, self.optimizer.generation)
            if result["status"] != "ok":
                LOG.info("candidate %s: %s (%s)", entry["x"], result["status"], result["reason"])
            same = unique[entry["key"]]
            fitness[same] = result["fitness"]
            bound[same] = result["status"] == "stopped"
            known.extend(same)
            if not again:
                self.bar.update(len(same))

    def _likeliest_best_first(self, candidates: np.ndarray) -> np.ndarray:
        """The order of ``candidates`` (physical units) by the fitness the log predicts."""
        complete = [e for e in self.log.entries if e["status"] != "stopped"]
        evaluated = np.array([e["x"] for e in complete], dtype=np.float64).reshape(
            len(complete), candidates.shape[1]
        )
        return likeliest_best_first(
            self.config.to_unit(candidates),
            self.config.to_unit(evaluated),
            np.array([e["fitness"] for e in complete]),
        )

    def _answer_from_log(
        self, candidates: np.ndarray, fitness: np.ndarray, bound: np.ndarray
    ) -> list[int]:
        """Fill ``fitness`` (and ``bound``: a stopped candidate's lower bound) from the log where
        it answers; the rows it does not answer."""
        missing = []
        for i, x in enumerate(candidates):
            entry = self.log.lookup(x)
            if entry is None or (
                entry["status"] == "stopped" and entry["generation"] != self.optimizer.generation
            ):  # a lower bound holds only against its own generation's cutoff
                missing.append(i)
            else:
                fitness[i] = entry["fitness"]
                bound[i] = entry["status"] == "stopped"
                self.reused += entry["key"] in self.logged_before
        self.bar.update(len(candidates) - len(missing))
        return missing


def run_loop(
    optimizer: Optimizer,
    config: OptimizeConfig,
    log: EvaluationLog,
    evaluator: Evaluator,
    early_stop: bool,
    out_dir: Path,
    progress: bool,
) -> tuple[int, float]:
    """Run the loop to its end, then free the evaluator, the log and the optimizer.

    Returns
    -------
    tuple
        Evaluations answered from entries logged before this run, and the loop's wall time
        (s, until everything is freed).

    Raises
    ------
    CampaignError
        When the Dask scheduler is lost; the message tells how to resume.
    """
    start = time.perf_counter()
    bar = tqdm(
        total=optimizer.budget, unit="eval", disable=not progress, desc=method_label(optimizer.name)
    )
    loop = AskTellLoop(optimizer, config, log, evaluator, early_stop, bar)
    try:
        loop.run(out_dir, start)
    except SchedulerError as exc:
        raise CampaignError(
            f"{exc}; every completed evaluation is in {log.path}: continue with --resume {out_dir}"
        ) from exc
    finally:
        bar.close()
        evaluator.close()
        log.close()
        optimizer.close()
    return loop.reused, time.perf_counter() - start
