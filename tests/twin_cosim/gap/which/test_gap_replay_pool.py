"""Where a diagnosis' time goes (phase totals, each fit's figures and the wall time of a batch
on idle workers); the judging replays and training residuals answered by the cache as fresh
ones; and the
calibration correction of a model, linear and then replayed, on a stand-in pool whose held-out
residual is an analytic sine."""

from __future__ import annotations

import dataclasses
from concurrent.futures import Future
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

from twin_cosim.gap.data.context import DEFAULT_CONTEXT
from twin_cosim.gap.data.residuals import Residuals
from twin_cosim.gap.floors.evidence import floor_of
from twin_cosim.gap.floors.noise import Floors
from twin_cosim.gap.settings import DiagnosisSettings
from twin_cosim.gap.which.acceptance import Judging
from twin_cosim.gap.which.replay import (
    FitTask,
    JointFitTask,
    Replays,
    ResidualTask,
    SimulateTask,
    Timed,
)
from twin_cosim.gap.which.replay_pool import (
    JudgingCache,
    PhaseTimes,
    ReplayPool,
    calibration_moves,
    makespan,
)
from twin_cosim.plant_model import plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.workers import BoundPool, SerialPool, Started


def test_phase_times_add_up():
    times = PhaseTimes()
    with times.timed("fits", tasks=3) as phase:
        phase.replays += 30
        phase.cpu_s += 6.0
    with times.timed("fits", tasks=1) as phase:
        phase.replays += 5
    with times.timed("replays", tasks=2) as phase:
        phase.replays += 2
        phase.cpu_s += 1.0
    table = times.as_dict()
    assert table["fits"]["tasks"] == 4 and table["fits"]["replays"] == 35
    assert table["total"]["replays"] == 37 and table["total"]["tasks"] == 6
    assert table["total"]["cpu_s"] == 7.0
    assert table["total"]["wall_s"] >= table["fits"]["wall_s"] >= 0.0


def test_makespan_of_tasks_in_order_on_free_workers():
    assert makespan([], 2) == 0.0
    assert makespan([3.0, 1.0, 1.0, 1.0], 2) == 3.0  # the short ones share the second worker
    assert makespan([1.0, 1.0, 3.0], 2) == 4.0  # the long one last waits for a free worker
    assert makespan([2.0, 2.0], 1) == 4.0


def _pool(spec, cache: bool) -> ReplayPool:
    """A replay pool of one worker in this process over ``spec``, its judging cache or none."""
    judging = SimpleNamespace()  # the tasks alone never judge
    return ReplayPool(
        BoundPool(SerialPool(), spec),
        dict(spec.nominal),
        [],
        judging,
        0.03,
        cache=JudgingCache.of(spec) if cache else None,
    )


def test_a_replay_asked_again_is_answered_by_the_cache_as_a_fresh_replay(small_spec):
    spec = small_spec()
    cached, fresh = _pool(spec, cache=True), _pool(spec, cache=False)
    try:
        level = {"stribeck_friction": 0.15, "stribeck_speed": 0.5}
        beyond = {**level, "stribeck_friction": -1.0}  # clipped to 0: the set of ``zero``
        zero = {**level, "stribeck_friction": 0.0}
        tasks = [SimulateTask(level), SimulateTask(beyond), SimulateTask(zero)]  # zero: again
        later = [
            SimulateTask(level, with_training=True),  # a time split: its training is judged
            SimulateTask(level),
        ]
        answers = cached.tasks("replays", tasks) + cached.tasks("replays", later)
        reference = fresh.tasks("replays", tasks + later)
        for got, expected in zip(answers, reference, strict=True):
            for record, fresh_record in zip(got.judging, expected.judging, strict=True):
                assert np.array_equal(record.to_numpy(), fresh_record.to_numpy())  # bit for bit
            assert (got.training is None) == (expected.training is None)
        training, fresh_training = answers[3].training[0], reference[3].training[0]
        assert np.array_equal(training.to_numpy(), fresh_training.to_numpy())
        phase = cached.times.as_dict()["replays"]
        assert (phase["tasks"], phase["replays"]) == (5, 5)
        assert (phase["replays_run"], phase["cache_hits"]) == (2, 3)
        assert fresh.times.as_dict()["replays"]["replays_run"] == 5
    finally:
        cached.pool.pool.close()
        fresh.pool.pool.close()


def test_a_residual_of_a_replayed_set_is_answered_by_the_cache_as_the_workers(small_spec):
    """A time split: the training residual of a parameter set whose judging replay the pool ran
    (or was handed, as the nominal twin's) is the worker's own, number for number, without a
    replay; a set not replayed runs."""
    spec = small_spec()
    cached, fresh = _pool(spec, cache=True), _pool(spec, cache=False)
    try:
        level = {"stribeck_friction": 0.15, "stribeck_speed": 0.5}
        other = {**level, "stribeck_friction": 0.1}
        (nominal,) = fresh.tasks("replays", [SimulateTask({}, with_training=True)])
        cached.keep({}, nominal)
        cached.tasks("replays", [SimulateTask(level)])
        asked = [ResidualTask(level), ResidualTask({}), ResidualTask(other)]
        answers = cached.tasks("residuals", asked)
        reference = fresh.tasks("residuals", asked)
        for got, expected in zip(answers, reference, strict=True):
            assert np.array_equal(got, expected)
        phase = cached.times.as_dict()["residuals"]
        assert (phase["replays"], phase["replays_run"], phase["cache_hits"]) == (3, 1, 2)
    finally:
        cached.pool.pool.close()
        fresh.pool.pool.close()


def test_a_residual_off_the_replays_time_grid_is_the_workers_too(small_spec):
    """A training window that ends between two samples of the replay, its last measured
    sample an ulp after the last one kept: the worker's cut replay holds its last value there,
    the whole run's goes on to the next sample; cut alike, the two residuals are the same."""
    spec = small_spec()
    training = dataclasses.replace(
        spec.training, t=[spec.training.t[0] * (1.0 + 2.3e-16)], end=0.50013
    )
    spec = dataclasses.replace(spec, training=training)
    cached, fresh = _pool(spec, cache=True), _pool(spec, cache=False)
    try:
        level = {"stribeck_friction": 0.15, "stribeck_speed": 0.5}
        cached.tasks("replays", [SimulateTask(level)])
        (got,) = cached.tasks("residuals", [ResidualTask(level)])
        (expected,) = fresh.tasks("residuals", [ResidualTask(level)])
        assert cached.times.as_dict()["residuals"]["replays_run"] == 0
        assert np.array_equal(got, expected)
    finally:
        cached.pool.pool.close()
        fresh.pool.pool.close()


def test_each_fit_is_recorded_with_its_replays_and_times(small_spec):
    pool = _pool(small_spec(), cache=True)
    try:
        fits = pool.tasks(
            "fits", [FitTask("coulomb_change", {}, DEFAULT_CONTEXT), SimulateTask({})]
        )
        (record,) = pool.times.as_dict()["fits"]["fits"]  # the replay task is no fit
        assert record["fit"] == "coulomb_change" and record["replays"] == fits[0].replays
        assert record["replays_run"] + record["cache_hits"] == fits[0].replays + 1
        assert record["iterations"] == fits[0].iterations >= 1
        assert record["cpu_s"] > 0 and record["wall_s"] > 0
        total = pool.times.as_dict()["total"]
        assert total["replays_run"] == record["replays_run"] + 1 and "fits" not in total
    finally:
        pool.pool.pool.close()


def test_a_joint_refit_run_here_is_the_workers_refit_its_jacobian_one_batch(small_spec):
    """The refit of a Stribeck curve started 25 % low with two calibrated parameters, run by
    the pool (its residuals as pool tasks) and by a worker alone: the same numbers; each of its
    Jacobians' four points went out as one batch, beside the sequential replay its start's."""
    spec = small_spec()
    task = JointFitTask(
        ("stribeck",),
        ((0.15, 0.4),),  # N.m, rad/s: the truth is 0.2 N.m at 0.4 rad/s
        (dict(DEFAULT_CONTEXT),),
        ("motor_inertia", "coulomb_friction"),
        0.03,
    )
    library = {h.name: h for h in plant_model("drive2mass").hypotheses}
    pool = _pool(spec, cache=True)
    batches: list[list] = []
    asked = pool.tasks

    def recorded(phase: str, tasks: list) -> list:
        batches.append(tasks)
        return asked(phase, tasks)

    pool.tasks = recorded  # type: ignore[method-assign]
    worker = spec.build()
    try:
        (fit,), (beside,) = pool.joint_fits("joint_refits", [task], library, [SimulateTask({})])
        alone = worker.joint_fit(task)
    finally:
        pool.pool.pool.close()
        worker.close()
    assert fit == alone
    assert fit.values["stribeck.stribeck_friction"] == pytest.approx(0.2, rel=0.05)
    assert isinstance(beside, Replays) and isinstance(batches[0][1], SimulateTask)
    sizes = [len(b) for b in batches]
    assert sizes[0] == 2 and sizes.count(4) == fit.iterations >= 1  # 2 effect + 2 calibrated
    assert all(isinstance(t, ResidualTask) for b in batches for t in b if b is not batches[0])
    assert sum(sizes) - 1 == fit.replays  # the start, each point and each Jacobian's points
    (record,) = pool.times.as_dict()["joint_refits"]["fits"]
    assert record["fit"] == "stribeck" and record["replays"] == fit.replays
    assert record["iterations"] == fit.iterations and record["wall_s"] > 0


# --- the calibration correction: linear, then replayed and re-linearised

SPACING_S = 0.005
TIME_S = np.arange(2000) * SPACING_S  # 10 s of held-out samples
OMEGA_RAD_S = 7.5  # a sine whose frequency scales with the calibrated parameter "stiffness"
AMPLITUDE = 20.0  # in noise floors


def _output(stiffness: float) -> np.ndarray:
    """The twin's output: a sine whose frequency goes with the square root of the stiffness (a
    resonance); a few % of stiffness shift its phase by a radian over 10 s."""
    return AMPLITUDE * np.sin(OMEGA_RAD_S * np.sqrt(stiffness) * TIME_S)


@dataclass
class _SinePool:
    """Replays whose held-out residual is the measured output minus the twin's."""

    measured: np.ndarray
    workers: int = 1
    asked: list = field(default_factory=list)

    def imap(self, tasks: list):
        for i, task in enumerate(tasks):
            self.asked.append(task)
            residual = self.measured - _output(task.overrides.get("stiffness", 1.0))
            yield i, Timed(Replays(None, [residual]), 0.0)


class _SineJudging(Judging):
    """Held-out runs of 10 s whose position residual is the replay's own (floors of 1)."""

    def __init__(self) -> None:
        super().__init__([], [], [], Floors(1.0, 1.0, "given", "given"))

    @property
    def duration_s(self) -> float:
        return float(TIME_S[-1])

    def residuals(self, replays: Replays) -> Residuals:
        zeros = np.zeros(len(TIME_S))
        return Residuals(TIME_S, replays.judging[0], zeros, zeros, zeros, zeros, zeros)


def _sine_pool(true_stiffness: float) -> ReplayPool:
    pool = _SinePool(_output(true_stiffness))
    return ReplayPool(pool, {"stiffness": 1.0}, ["stiffness"], _SineJudging(), tolerance=0.03)


def test_a_calibration_error_the_linear_correction_underestimates_is_explained_by_its_replays():
    replay_pool = _sine_pool(1.05)  # +5 % stiffness: +2.5 % in frequency, 0.9 rad over 10 s
    judging = replay_pool.judging
    threshold = judging.threshold(DiagnosisSettings())
    nominal = replay_pool.tasks("replays", [SimulateTask({})])[0]
    linear = floor_of(replay_pool.basis({}), judging.vector(judging.residuals(nominal)))
    assert linear.left >= threshold  # the centred differences at nominal leave a gap

    floor, calibrated = replay_pool.calibration({}, nominal, threshold)

    # Gauss-Newton within the tolerance: the stiffness at +3 % (its bound), and what is left
    # is what a +3 % stiffness cannot explain of a +5 % one, replayed
    assert floor.coefficients["stiffness"] == pytest.approx(1.0, abs=1e-6)
    left = np.linalg.norm(judging.vector(judging.residuals(calibrated)))
    assert floor.left == pytest.approx(left)
    expected = np.linalg.norm(_output(1.05) - _output(1.03)) / np.sqrt(2 * len(TIME_S))
    assert floor.left == pytest.approx(expected, rel=1e-9)
    assert floor.left < linear.left
    assert floor.explained**2 + floor.left**2 == pytest.approx(floor.before**2)


def test_a_calibration_error_within_tolerance_is_explained_to_the_noise():
    replay_pool = _sine_pool(1.055**0.5)  # +2.7 % stiffness, within the 3 % tolerance
    judging = replay_pool.judging
    threshold = judging.threshold(DiagnosisSettings())
    nominal = replay_pool.tasks("replays", [SimulateTask({})])[0]
    linear = floor_of(replay_pool.basis({}), judging.vector(judging.residuals(nominal)))

    floor, _ = replay_pool.calibration({}, nominal, threshold)

    assert linear.left >= threshold  # linearised at nominal, a gap would be left ...
    assert floor.left < threshold  # ... that the replayed correction explains
    assert floor.coefficients["stiffness"] == pytest.approx((1.055**0.5 - 1.0) / 0.03, abs=0.02)


def test_a_gap_the_linear_correction_already_explains_is_not_replayed_further():
    replay_pool = _sine_pool(1.002)  # a tiny error: the linear correction is exact enough
    judging = replay_pool.judging
    threshold = judging.threshold(DiagnosisSettings())
    nominal = replay_pool.tasks("replays", [SimulateTask({})])[0]
    asked = len(replay_pool.pool.asked)

    floor, _ = replay_pool.calibration({}, nominal, threshold)

    assert floor.left < threshold
    # the two calibration directions and the corrected replay, no re-linearisation
    assert len(replay_pool.pool.asked) - asked == 3


def _stiffness_pool(measured: np.ndarray, started: Started | None = None) -> ReplayPool:
    """A sine pool over the stiffness, 3 % tolerance, with calibration directions started
    ahead (``started``) or none."""
    return ReplayPool(
        _SinePool(measured),
        {"stiffness": 1.0},
        ["stiffness"],
        _SineJudging(),
        0.03,
        nominal_directions=started,
    )


def test_calibration_directions_started_ahead_make_the_nominal_basis_without_a_replay():
    """The nominal twin's directions given out before the pool was made (while the parent found
    the noise): the same basis as replayed by the pool, counted once, nothing asked again;
    directions of another twin are cancelled and the pool replays the basis."""
    measured = _output(1.02)
    fresh = _stiffness_pool(measured)
    tasks = calibration_moves({"stiffness": 1.0}, {}, ["stiffness"], 0.03)
    futures = []
    for task in tasks:
        future: Future = Future()
        residual = measured - _output(task.overrides["stiffness"])
        future.set_result(Timed(Replays(None, [residual]), 0.1, replays_run=1))
        futures.append(future)
    ahead = _stiffness_pool(measured, Started(tasks, futures))
    assert np.array_equal(ahead.basis({}).directions, fresh.basis({}).directions)
    assert ahead.pool.asked == [] and len(fresh.pool.asked) == 2
    phase = ahead.times.as_dict()["calibration_directions"]
    assert (phase["tasks"], phase["replays"], phase["replays_run"]) == (2, 2, 2)
    ahead.basis({"stiffness": 1.01})  # another model's directions: replayed on the pool
    assert len(ahead.pool.asked) == 2

    other = calibration_moves({"stiffness": 1.0}, {}, ["stiffness"], 0.05)  # not this twin's
    waiting: list[Future] = [Future(), Future()]
    mismatched = _stiffness_pool(measured, Started(other, waiting))
    assert np.array_equal(mismatched.basis({}).directions, fresh.basis({}).directions)
    assert len(mismatched.pool.asked) == 2 and all(f.cancelled() for f in waiting)


def test_the_judging_cache_keeps_the_latest_replays_within_its_bytes():
    """Each record of 100 samples of two columns holds 1600 bytes: a cache of 4000 bytes keeps
    the two latest parameter sets; asking one again (as a put of the same set) counts it once."""
    cache = JudgingCache(lambda overrides: tuple(sorted(overrides.items())), None, size_bytes=4000)

    def replays(value: float) -> Replays:
        return Replays(None, [RunRecord(np.full((100, 2), value), ["t", "x"])])

    for k in range(4):
        cache.put(SimulateTask({"backlash": float(k)}), replays(k))
    cache.put(SimulateTask({"backlash": 3.0}), replays(3))
    kept = [key[0] for key in cache.entries]
    assert kept == [(("backlash", 2.0),), (("backlash", 3.0),)]
    assert cache.kept_bytes == 3200
    assert cache.get(SimulateTask({"backlash": 0.0})) is None
    assert cache.get(SimulateTask({"backlash": 2.0})).judging[0]["x"][0] == 2.0


def test_the_judging_cache_keeps_the_latest_training_residuals_within_their_bytes():
    """A time split's training replays are its judging replays: each put keeps their residual
    (100 floats, 800 bytes); 2000 bytes hold the two latest. A replaced entry of another size
    counts at its new size."""
    cache = JudgingCache(
        lambda overrides: tuple(sorted(overrides.items())),
        [0],
        lambda records: records[0]["x"].copy(),
        size_bytes=10_000,
        residual_bytes=2000,
    )
    for k in range(3):
        record = RunRecord(np.full((100, 2), float(k)), ["t", "x"])
        cache.put(SimulateTask({"backlash": float(k)}), Replays(None, [record]))
    assert [key[0][1] for key in cache.residuals] == [1.0, 2.0]
    assert cache.kept_residual_bytes == 1600
    assert cache.residual({"backlash": 2.0})[0] == 2.0
    assert cache.residual({"backlash": 0.0}) is None
    longer = RunRecord(np.full((300, 2), 1.0), ["t", "x"])
    cache.put(SimulateTask({"backlash": 1.0}), Replays(None, [longer]))
    assert cache.kept_bytes == 3 * 1600 - 1600 + 4800
