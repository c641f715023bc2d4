"""The co-simulation master: both paths agree (one axis and several, with the injections), each
axis runs as it would alone, any contract FMU runs, failures stop with the log."""

from __future__ import annotations

import dataclasses
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twin_cosim.controller_set import TABLE3
from twin_cosim.cosim import (
    RECORD_COLUMNS,
    SPEED_LOOP_COLUMNS,
    AxisRun,
    Injections,
    RunAborted,
    run_axes,
    run_scenario,
)
from twin_cosim.plant import Plant, PlantError
from twin_cosim.reference import ReferenceGrid
from twin_cosim.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


@pytest.fixture(scope="module")
def reference1():
    return load_scenario(SCENARIOS / "reference1.yaml")


def test_fast_and_reference_paths_agree_on_reference1(plant, reference1):
    fast = run_scenario(plant, reference1, fast=True)
    slow = run_scenario(plant, reference1, fast=False)
    assert list(fast.columns) == list(RECORD_COLUMNS)
    assert len(fast) == len(reference1.reference.position)
    assert np.max(np.abs(fast["x"] - slow["x"])) < 1e-9
    assert np.max(np.abs(fast["current"] - slow["current"])) < 1e-9


def test_reset_between_runs_repeats_the_run(plant, reference1):
    first = run_scenario(plant, reference1)
    second = run_scenario(plant, reference1)
    assert first.columns == second.columns
    assert np.array_equal(first.to_numpy(), second.to_numpy())


def test_time_is_index_times_period(plant, reference1):
    record = run_scenario(plant, reference1)
    assert np.array_equal(record["t"], np.arange(len(record)) * 250e-6)


def test_another_fmu_with_the_contract_runs(fmu_path, reference1, tmp_path):
    copy = tmp_path / "vendor_axis.fmu"
    shutil.copy(fmu_path, copy)
    with Plant(copy) as other, Plant(fmu_path) as ours:
        theirs, own = run_scenario(other, reference1), run_scenario(ours, reference1)
        assert np.array_equal(theirs.to_numpy(), own.to_numpy())


def rewrite_description(fmu_path: Path, target: Path, old: str, new: str) -> Path:
    with zipfile.ZipFile(fmu_path) as source, zipfile.ZipFile(target, "w") as out:
        for item in source.infolist():
            data = source.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(old.encode(), new.encode())
            out.writestr(item, data)
    return target


def test_fmu_without_the_contract_is_refused(fmu_path, tmp_path):
    broken = rewrite_description(
        fmu_path, tmp_path / "broken.fmu", 'name="load_position"', 'name="x_load"'
    )
    with pytest.raises(
        PlantError, match="does not offer the plant contract: missing output 'load_position'"
    ):
        Plant(broken)


def test_missing_and_corrupt_fmu_are_named(tmp_path):
    with pytest.raises(PlantError, match="FMU file not found"):
        Plant(tmp_path / "nothing.fmu")
    junk = tmp_path / "junk.fmu"
    junk.write_text("not a zip")
    with pytest.raises(PlantError, match="not an FMU"):
        Plant(junk)


@pytest.mark.parametrize("fast", [True, False])
def test_failing_fmu_stops_the_run_with_its_message(plant, reference1, fast):
    # A 20 kHz coupling cannot be integrated with 4 substeps of 62.5 us: doStep fails.
    with pytest.raises(PlantError, match="too long"):
        run_scenario(plant, reference1, fast=fast, plant_overrides={"resonance_frequency": 20000.0})
    run_scenario(plant, reference1)  # and the plant is usable again


def test_unknown_plant_parameter_is_named(plant, reference1):
    with pytest.raises(PlantError, match="no parameter named 'stiffnes'"):
        run_scenario(plant, reference1, plant_overrides={"stiffnes": 1.0})


@pytest.mark.parametrize("recorded", [False, True])
def test_a_command_disturbance_is_cancelled_by_the_integral_action(plant, tmp_path, recorded):
    """A constant offset added to the controller's output before the plant, at standstill
    without friction or backlash: the speed loop's integral drives its own output to minus the
    offset and the position error to zero; the recorded command includes the offset exactly
    when the scenario says the measured one does."""
    import dataclasses

    text = (SCENARIOS / "reference1.yaml").read_text().split("reference:")[0]
    path = tmp_path / "dwell.yaml"
    path.write_text(text + "reference:\n  sample_period: 0.004\n  segments:\n    - dwell: 1.5\n")
    scenario = load_scenario(path)
    offset = 0.2  # A
    n = len(scenario.reference.position)
    dwell = dataclasses.replace(
        scenario, command_disturbance=np.full(n, offset), disturbance_in_record=recorded
    )
    ideal = {"coulomb_friction": 0.0, "viscous_friction": 0.0, "backlash": 0.0}
    fast = run_scenario(plant, dwell, plant_overrides=ideal)
    slow = run_scenario(plant, dwell, fast=False, plant_overrides=ideal)
    assert np.max(np.abs(fast["current"] - slow["current"])) < 1e-9
    early = fast["current"][fast["t"] < 0.05] - (offset if recorded else 0.0)
    assert early.min() < -offset  # the loop first answers the push, then settles
    end = fast["t"] > 1.0
    expected = 0.0 if recorded else -offset
    assert fast["current"][end] == pytest.approx(expected, abs=1e-6)
    assert np.max(np.abs(fast["x"][end])) < 1e-12


@pytest.fixture(scope="module")
def grids():
    reference = load_scenario("reference1").reference
    n = 6000  # 1.5 s: dwell, then the first ramps
    x = ReferenceGrid(
        reference.period,
        reference.position[:n],
        reference.velocity[:n],
        reference.acceleration[:n],
    )
    y = ReferenceGrid(x.period, -0.5 * x.position, -0.5 * x.velocity, -0.5 * x.acceleration)
    return x, y


@pytest.fixture()
def plants(fmu_path):
    made = [Plant(fmu_path, instance_name=name) for name in ("X", "Y", "alone")]
    yield made
    for plant in made:
        plant.close()


def _axes(plants, grids, injections=None):
    scenario = load_scenario("reference1")
    injections = injections or (Injections(), Injections())
    return [
        AxisRun("X", plants[0], grids[0], TABLE3["ft"], scenario.settings, {}, injections[0]),
        AxisRun(
            "Y",
            plants[1],
            grids[1],
            TABLE3["ga"],
            scenario.settings,
            {"backlash": 2e-5},
            injections[1],
        ),
    ]


def test_fast_and_reference_paths_agree_and_each_axis_runs_as_alone(plants, grids):
    axes = _axes(plants, grids)
    fast = run_axes(axes)
    slow = run_axes(axes, fast=False)
    for name in ("X", "Y"):
        assert (
            np.max(
                np.abs(fast[name].position_loop.to_numpy() - slow[name].position_loop.to_numpy())
            )
            < 1e-12
        )
        assert fast[name].speed_loop is None
    alone = run_axes(
        [AxisRun("Y", plants[2], grids[1], TABLE3["ga"], axes[1].settings, {"backlash": 2e-5})]
    )["Y"]
    assert np.array_equal(fast["Y"].position_loop.to_numpy(), alone.position_loop.to_numpy())
    assert not np.array_equal(fast["X"].position_loop["x"], fast["Y"].position_loop["x"])


def _signals(grid, ratio, seed):
    """Each injection of :class:`Injections`: small random signals at their rates."""
    rng = np.random.default_rng(seed)
    n = len(grid.position)
    return Injections(
        load_torque=rng.normal(0.0, 0.01, n * ratio),
        current=rng.normal(0.0, 0.05, n * ratio),
        speed=rng.normal(0.0, 0.01, n * ratio),
        position=rng.normal(0.0, 1e-7, n),
        speed_noise=rng.normal(0.0, 0.002, n * ratio),
    )


def test_the_injections_and_the_speed_loop_record_are_the_same_on_both_paths(plants, grids):
    ratio = load_scenario("reference1").settings.speed_steps_per_position_step
    injections = (
        _signals(grids[0], ratio, 1),
        Injections(current=_signals(grids[1], ratio, 2).current),
    )
    axes = _axes(plants, grids, injections)
    fast = run_axes(axes, speed_loop_record=True)
    slow = run_axes(axes, fast=False, speed_loop_record=True)
    for name in ("X", "Y"):
        found, expected = fast[name], slow[name]
        assert np.array_equal(found.position_loop.to_numpy(), expected.position_loop.to_numpy())
        assert np.array_equal(found.speed_loop.to_numpy(), expected.speed_loop.to_numpy())
        assert found.speed_loop.columns == list(SPEED_LOOP_COLUMNS)
        assert len(found.speed_loop) == len(grids[0].position) * ratio
    x = fast["X"]
    # the record's error is the position setpoint (with its injection) minus the position
    record = x.position_loop
    assert np.array_equal(record["error"], (record["x_ref"] + injections[0].position) - record["x"])
    # the speed-loop record holds the current the plant received: the controller's plus the
    # injection; the position-loop record the controller's own, averaged
    controller_current = x.speed_loop["current"] - injections[0].current
    means = controller_current.reshape(-1, ratio).mean(axis=1)
    assert np.max(np.abs(means - record["current"])) < 1e-9
    # the loop read the measured speed with its noise: at the first sample of each position
    # period that is the recorded motor speed plus the noise
    first = x.speed_loop["speed"][::ratio] - injections[0].speed_noise[::ratio]
    assert np.max(np.abs(first - record["motor_speed"])) < 1e-12
    # each injection acts: without them the axis runs otherwise
    plain = run_axes(_axes(plants, grids))["X"].position_loop
    assert not np.array_equal(plain["x"], record["x"])


@pytest.mark.parametrize("fast", [True, False])
def test_an_injection_of_the_wrong_length_is_named(plants, grids, fast):
    injections = (Injections(speed=np.zeros(5)), Injections())
    with pytest.raises(ValueError, match="axis X: the speed injection must be"):
        run_axes(_axes(plants, grids, injections), fast)


def test_an_axis_leaving_the_band_stops_the_run_naming_it(plants, grids):
    axes = _axes(plants, grids)
    for fast in (True, False):
        with pytest.raises(RunAborted, match="axis [XY]"):
            run_axes(axes, fast, abort_error=1e-7)


def test_axes_must_share_rates_and_have_their_own_instance(plants, grids):
    axes = _axes(plants, grids)
    shared = [axes[0], AxisRun("Y", plants[0], grids[1], TABLE3["ft"], axes[0].settings)]
    with pytest.raises(ValueError, match="own plant instance"):
        run_axes(shared)
    short = ReferenceGrid(grids[1].period, *(a[:100] for a in (grids[1].position,) * 3))
    with pytest.raises(ValueError, match="axis Y"):
        run_axes([axes[0], AxisRun("Y", plants[1], short, TABLE3["ft"], axes[0].settings)])


@pytest.fixture(scope="module")
def fmi3_fmu():
    from fmu_build.build import build_fmu

    return build_fmu("drive2mass", fmi_version=3)


def test_an_fmi3_plant_runs_on_both_paths_as_the_fmi2_plant(fmu_path, fmi3_fmu, reference1):
    """The FMI 3.0 FMU of the same sources gives the FMI 2.0 FMU's trajectory (1e-12), alone and
    as one axis beside an FMI 2.0 axis of the same run."""
    with Plant(fmi3_fmu) as three, Plant(fmu_path) as two:
        assert (three.fmi_version, two.fmi_version) == (3, 2)
        for fast in (True, False):
            theirs = run_scenario(three, reference1, fast=fast).to_numpy()
            own = run_scenario(two, reference1, fast=fast).to_numpy()
            assert np.max(np.abs(theirs - own)) <= 1e-12
    with Plant(fmi3_fmu, "X3") as three, Plant(fmu_path, "Y2") as two:
        grid = reference1.reference
        settings = reference1.settings
        axes = [
            AxisRun("X", three, grid, TABLE3["ft"], settings, {"backlash": 2e-5}),
            AxisRun("Y", two, grid, TABLE3["ft"], settings, {"backlash": 2e-5}),
        ]
        records = run_axes(axes)
        x, y = records["X"].position_loop.to_numpy(), records["Y"].position_loop.to_numpy()
        assert np.max(np.abs(x - y)) <= 1e-12


def test_a_failing_fmi3_call_stops_the_run_with_its_message(fmi3_fmu, reference1):
    """fmi3DoStep fails inside the loop (a 20 kHz coupling, 4 substeps of 62.5 us): both paths
    stop with the FMU's message, and the plant runs again after it."""
    too_stiff = {"resonance_frequency": 20000.0}
    with Plant(fmi3_fmu) as plant:
        with pytest.raises(PlantError, match="fmi3 call failed with status 3(.|\n)*too long"):
            run_scenario(plant, reference1, plant_overrides=too_stiff)
        with pytest.raises(PlantError, match="fmi3DoStep failed(.|\n)*too long"):
            run_scenario(plant, reference1, fast=False, plant_overrides=too_stiff)
        run_scenario(plant, reference1)
    with Plant(fmi3_fmu) as plant, pytest.raises(PlantError, match="fmi3SetFloat64.*backlash"):
        run_scenario(plant, reference1, plant_overrides={"backlash": -1.0})


@pytest.mark.parametrize("fast", [True, False])
def test_an_open_loop_run_steps_the_plant_with_the_given_command(plants, grids, fast):
    """The open-loop option: the plant receives the command array in place of the speed loop's
    (plus a current injection), sample by sample, exactly as a loop that sets it and steps the
    FMU itself; the record's current is that command."""
    scenario = load_scenario("reference1")
    ratio = scenario.settings.speed_steps_per_position_step
    n = len(grids[0].position)
    rng = np.random.default_rng(3)
    command = np.repeat(rng.normal(0.0, 2.0, n), ratio)
    added = rng.normal(0.0, 0.1, n * ratio)
    axis = AxisRun(
        "X",
        plants[0],
        grids[0],
        TABLE3["ft"],
        scenario.settings,
        {},
        Injections(open_loop=command, current=added),
    )
    found = run_axes([axis], fast, speed_loop_record=True)["X"]
    assert np.array_equal(found.speed_loop["current"], command + added)
    assert np.max(np.abs(found.position_loop["current"] - command[::ratio])) < 1e-12
    plant = plants[2]
    plant.start_run({})
    vr_in = [plant.value_reference("current_cmd")]
    vr_out = [plant.value_reference(n) for n in ("load_position", "motor_speed")]
    h = scenario.settings.speed_period
    expected = []
    for k, value in enumerate(command + added):
        if k % ratio == 0:
            expected.append(plant.get_reals(vr_out))
        plant.set_reals(vr_in, [float(value)])
        plant.do_step(k * h, h)
    expected = np.array(expected)
    assert np.array_equal(found.position_loop["x"], expected[:, 0])
    assert np.array_equal(found.position_loop["motor_speed"], expected[:, 1])


def test_a_reference_sampled_off_the_position_period_is_refused(plants, grids):
    """A controller set may change the position period: the run refuses a reference sampled at
    another period instead of stepping with the wrong speed-loop step."""
    axes = _axes(plants, grids)
    settings = dataclasses.replace(axes[0].settings, position_period=500e-6)
    with pytest.raises(ValueError, match="axis X: its reference is sampled every 0.00025 s"):
        run_axes([dataclasses.replace(axes[0], settings=settings)])
