"""The lockstep master: both paths agree, and each axis runs as it would alone."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.contour.lockstep import AxisRun, run_axes_fast, run_axes_reference
from twin_cosim.cosim import RunAborted, run_fast_path
from twin_cosim.paper import TABLE3
from twin_cosim.plant import Plant
from twin_cosim.reference import ReferenceGrid
from twin_cosim.scenario import load_scenario


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


def _axes(plants, grids):
    scenario = load_scenario("reference1")
    return [
        AxisRun("X", plants[0], grids[0], TABLE3["ft"], scenario.settings),
        AxisRun("Y", plants[1], grids[1], TABLE3["ga"], scenario.settings, {"backlash": 2e-5}),
    ]


def test_fast_and_reference_paths_agree_and_each_axis_runs_as_alone(plants, grids):
    axes = _axes(plants, grids)
    fast = run_axes_fast(axes)
    slow = run_axes_reference(axes)
    for name in ("X", "Y"):
        assert np.max(np.abs(fast[name].to_numpy() - slow[name].to_numpy())) < 1e-12
    alone = run_fast_path(plants[2], grids[1], TABLE3["ga"], axes[1].settings, {"backlash": 2e-5})
    assert np.array_equal(fast["Y"].to_numpy(), alone.to_numpy())
    assert not np.array_equal(fast["X"]["x"].to_numpy(), fast["Y"]["x"].to_numpy())


def test_an_axis_leaving_the_band_stops_the_run_naming_it(plants, grids):
    axes = _axes(plants, grids)
    for run in (run_axes_fast, run_axes_reference):
        with pytest.raises(RunAborted, match="axis [XY]"):
            run(axes, abort_error=1e-7)


def test_axes_must_share_rates_and_have_their_own_instance(plants, grids):
    axes = _axes(plants, grids)
    shared = [axes[0], AxisRun("Y", plants[0], grids[1], TABLE3["ft"], axes[0].settings)]
    with pytest.raises(ValueError, match="own plant instance"):
        run_axes_fast(shared)
    short = ReferenceGrid(grids[1].period, *(a[:100] for a in (grids[1].position,) * 3))
    with pytest.raises(ValueError, match="axis Y"):
        run_axes_fast([axes[0], AxisRun("Y", plants[1], short, TABLE3["ft"], axes[0].settings)])
