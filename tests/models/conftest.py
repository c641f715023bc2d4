"""The project models' slaves, for the tests that every model's slave must pass: a slave of each
model in each FMI version behind one set of version-neutral calls (FMI 2.0 through the twin's
Plant, FMI 3.0 through fmpy's FMU3Slave), so that a test of the shared slave
(models/common/slave.c) runs once through fmi2_slave.c and once through fmi3_slave.c; and one
open-loop run of each model that any importer can repeat."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi3 import FMU3Slave

from fmu_build.build import FMI_VERSIONS, build_fmu
from twin_cosim.plant import Plant, PlantError, extracted_fmu

MODELS = ("drive2mass", "emps", "hsm150")


class Fmi2Slave:
    """A model's FMI 2.0 slave through the twin's :class:`Plant`."""

    version = 2
    step_state = "StepComplete"
    real_type, integer_type = "Real", "Integer"

    def __init__(self, model: str) -> None:
        self.model = model
        self.plant = Plant(build_fmu(model), model)
        self.fmu = self.plant.fmu
        self.description = self.plant.description
        self.messages = self.plant.messages

    def function(self, name: str) -> str:
        """The API function's name: ``function("GetReal")`` is ``fmi2GetReal``."""
        return f"fmi2{name}"

    def vr(self, name: str) -> int:
        return self.plant.value_reference(name)

    def start_run(self, parameters: Mapping[str, float] | None = None, start_time: float = 0.0):
        """Reset, set parameters, initialise at ``start_time`` (s); PlantError on a failure."""
        self.plant.start_run(parameters, start_time)

    def enter_initialization(self, start_time: float = 0.0) -> None:
        self.fmu.setupExperiment(startTime=start_time)
        self.fmu.enterInitializationMode()

    def get_reals(self, vrs: Sequence[int]) -> list[float]:
        return self.fmu.getReal(list(vrs))

    def set_reals(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        self.fmu.setReal(list(vrs), list(values))

    def do_step(self, t: float, h: float) -> None:
        self.fmu.doStep(t, h)

    def close(self) -> None:
        self.plant.close()


class Fmi3Slave:
    """A model's FMI 3.0 slave through fmpy's FMU3Slave, with the calls of :class:`Fmi2Slave`.

    Parameters
    ----------
    model
        Name of a folder under ``models/``.
    event_mode_used
        Instantiate with eventModeUsed (the importer then passes through event mode).
    """

    version = 3
    step_state = "StepMode"
    real_type, integer_type = "Float64", "Int32"
    FUNCTIONS = {"GetReal": "GetFloat64", "SetReal": "SetFloat64", "SetInteger": "SetInt32"}

    def __init__(self, model: str, event_mode_used: bool = False) -> None:
        self.model = model
        fmu_path = build_fmu(model, fmi_version=3)
        self.description = read_model_description(str(fmu_path))
        self.variables = {v.name: v for v in self.description.modelVariables}
        self.messages: list[str] = []
        self.fmu = FMU3Slave(
            guid=self.description.guid,
            unzipDirectory=str(extracted_fmu(fmu_path)),
            modelIdentifier=model,
            instanceName=model,
        )
        self.fmu.instantiate(eventModeUsed=event_mode_used, logMessage=self._log)
        self._fresh = True

    def _log(self, _environment, _status, category: bytes, message: bytes) -> None:
        self.messages.append(f"[{category.decode()}] {message.decode()}")

    def function(self, name: str) -> str:
        """The API function's name: ``function("GetReal")`` is ``fmi3GetFloat64``."""
        return f"fmi3{self.FUNCTIONS.get(name, name)}"

    def vr(self, name: str) -> int:
        return self.variables[name].valueReference

    def start_run(self, parameters: Mapping[str, float] | None = None, start_time: float = 0.0):
        """Reset, set parameters, initialise at ``start_time`` (s); PlantError on a failure,
        with the FMU's messages, as :meth:`Plant.start_run` raises it."""
        self.messages.clear()
        try:
            if not self._fresh:
                self.fmu.reset()
            self._fresh = False
            for name, value in (parameters or {}).items():
                if self.variables[name].type == "Int32":
                    self.fmu.setInt32([self.vr(name)], [int(value)])
                else:
                    self.fmu.setFloat64([self.vr(name)], [float(value)])
            self.enter_initialization(start_time)
            self.fmu.exitInitializationMode()
        except Exception as exc:
            raise PlantError(f"{exc}: {self.messages}") from exc

    def enter_initialization(self, start_time: float = 0.0) -> None:
        self.fmu.enterInitializationMode(startTime=start_time)

    def get_reals(self, vrs: Sequence[int]) -> list[float]:
        return self.fmu.getFloat64(list(vrs))

    def set_reals(self, vrs: Sequence[int], values: Sequence[float]) -> None:
        self.fmu.setFloat64(list(vrs), list(values))

    def do_step(self, t: float, h: float) -> tuple[bool, bool, bool, float]:
        return self.fmu.doStep(t, h)

    def close(self) -> None:
        self.fmu.freeInstance()


# Per model: communication step (s), parameters, and the current command at step k (A or V):
# breakaway, a reversal through the backlash or friction, the dead time and the noise all act.
RUNS = {
    "drive2mass": (
        62.5e-6,
        {"load_position_start": 0.02, "noise_amplitude_1": 1e-7, "dead_time_steps": 2},
        lambda k: 2.5 if k < 1500 else -2.5,
    ),
    "emps": (1e-3, {"load_position_start": 0.1, "dead_time_steps": 2}, lambda k: 3.0 - k / 300),
    "hsm150": (
        1e-3,
        {
            "load_position_start": 0.1,
            "coulomb_friction": 0.03,
            "stribeck_friction": 0.01,
            "dead_time_steps": 2,
        },
        lambda k: 1.5 - k / 1000,
    ),
}
STEPS = 3000
# Parameters that give a model's axis a breakaway level where its catalogue has none (the
# stick-slip tests need the axis to stick).
BREAKAWAY = {"hsm150": {"coulomb_friction": 0.03}}


def outputs_of_a_run(slave: Fmi2Slave | Fmi3Slave, model: str) -> np.ndarray:
    """Every output after every step of the model's run, a disturbance changing halfway."""
    h, parameters, command = RUNS[model]
    slave.start_run(parameters)
    vr_in = [slave.vr("current_cmd"), slave.vr("disturbance_torque")]
    vr_out = [u.variable.valueReference for u in slave.description.outputs]
    rows = []
    for k in range(STEPS):
        slave.set_reals(vr_in, [command(k), 0.0 if k < STEPS // 2 else 0.05])
        slave.do_step(k * h, h)
        rows.append(slave.get_reals(vr_out))
    return np.array(rows)


SLAVES = {2: Fmi2Slave, 3: Fmi3Slave}


@pytest.fixture(params=FMI_VERSIONS, ids=lambda v: f"fmi{v}")
def slave(request):
    """drive2mass's slave in each FMI version, freed after the test."""
    instance = SLAVES[request.param]("drive2mass")
    yield instance
    instance.close()


@pytest.fixture(
    params=[(m, v) for m in MODELS for v in FMI_VERSIONS], ids=lambda p: f"{p[0]}-fmi{p[1]}"
)
def any_slave(request):
    """Each model's slave in each FMI version, freed after the test."""
    model, version = request.param
    instance = SLAVES[version](model)
    yield instance
    instance.close()
