"""Optimizer campaign speed on reference 1: a CE campaign with the paper's settings, and the
parallel efficiency of the process pool, measured in one run.

    python benchmarks/optimize_speed.py [--evaluations N]

Parallel efficiency = T(serial) / (workers x T(pool)) for the same batch of candidates, both
evaluators already started (worker start-up is reported apart).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from twin_cosim.optimize.axis_problem import AxisProblem, CampaignSpec, ObjectiveSpec
from twin_cosim.optimize.config import load_config
from twin_cosim.optimize.driver import run_campaign
from twin_cosim.scenario import load_scenario
from twin_cosim.workers import ProcessPool, SerialPool

SCENARIO = str(Path(__file__).resolve().parents[1] / "scenarios" / "reference1.yaml")


def timed_batch(evaluator, candidates: np.ndarray) -> float:
    start = time.perf_counter()
    for _ in evaluator.imap(candidates):
        pass
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--evaluations", type=int, default=200, help="batch size for the efficiency"
    )
    args = parser.parse_args()
    workers = os.cpu_count() or 1
    scenario = load_scenario(SCENARIO)
    config = load_config(scenario)
    candidates = config.from_unit(np.random.default_rng(0).uniform(0.2, 0.8, (args.evaluations, 6)))
    spec = ObjectiveSpec((scenario,), None, None)
    serial = SerialPool(spec)
    timed_batch(serial, candidates[:2])  # compiled loop loaded
    t_serial = timed_batch(serial, candidates)
    serial.close()
    start = time.perf_counter()
    pool = ProcessPool(spec, workers)
    timed_batch(pool, candidates[: 2 * workers])  # workers started and warm
    startup = time.perf_counter() - start
    t_pool = timed_batch(pool, candidates)
    pool.close()
    print(f"{args.evaluations} evaluations of reference 1 ({workers} cores)")
    print(f"  serial {t_serial:.2f} s ({t_serial / args.evaluations * 1e3:.1f} ms each)")
    print(f"  pool of {workers}: {t_pool:.2f} s; worker start-up {startup:.2f} s")
    print(f"  parallel efficiency {t_serial / (workers * t_pool):.1%}")
    with tempfile.TemporaryDirectory() as tmp:
        problem = AxisProblem.resolve(CampaignSpec(SCENARIO, "ce", seed=0))
        result = run_campaign(problem, Path(tmp) / "ce", progress=False)
    print(
        f"CE campaign, paper settings (Table 2), seed 0, pool of {workers}: "
        f"{result.wall_s:.1f} s wall, "
        f"{result.evaluations} evaluations, {result.generations} generations ({result.stop_reason})"
    )
    print(
        f"  best E_pk {result.metrics['E_pk_um']:.3f} um vs Fine-Tune "
        f"{result.reference['E_pk_um']:.3f} um "
        f"({result.metrics['E_pk_um'] / result.reference['E_pk_um']:.1%})"
    )


if __name__ == "__main__":
    main()
