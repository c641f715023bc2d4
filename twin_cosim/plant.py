"""Access to a plant FMU: load once, instantiate once, reset and parametrise per run.

Any FMI 2.0 or FMI 3.0 co-simulation FMU that offers the plant contract runs in the twin:

- inputs ``current_cmd`` [A] and ``disturbance_torque`` [N.m];
- outputs ``motor_angle`` [rad], ``motor_speed`` [rad/s], ``load_position`` [m] (the linear
  scale's reading) and ``load_speed`` [m/s].

Every FMI call is checked; a failure raises :class:`PlantError` with the FMU's logged messages.
The version's calls are behind a few methods (:meth:`Plant.set_reals`, :meth:`Plant.get_reals`,
:meth:`Plant.do_step`, :meth:`Plant.function_addresses`), so that the masters step either.
"""

from __future__ import annotations

import ctypes
import hashlib
import shutil
import tempfile
import zipfile
from collections.abc import Mapping
from pathlib import Path

from fmpy import calloc, extract, free, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)
from fmpy.fmi3 import FMU3Slave
from fmpy.logging import addLoggerProxy

from fmu_build.build import DEFAULT_MODEL, build_fmu, cache_dir

# The plant contract, the one place of its names: the co-simulation master sets the inputs and
# reads the outputs in these orders.
CONTRACT_INPUTS = ("current_cmd", "disturbance_torque")
CONTRACT_OUTPUTS = ("motor_angle", "motor_speed", "load_position", "load_speed")
# What each FMI version names its calls and its real type (the masters call these by address).
FMI_CALLS = {
    2: {"set": "fmi2SetReal", "step": "fmi2DoStep", "get": "fmi2GetReal"},
    3: {"set": "fmi3SetFloat64", "step": "fmi3DoStep", "get": "fmi3GetFloat64"},
}
REAL_TYPES = {2: "Real", 3: "Float64"}
INTEGER_TYPES = {2: "Integer", 3: "Int32"}


class PlantError(RuntimeError):
    """The plant FMU is missing, corrupt, lacks the plant contract, or an FMI call failed."""


def default_fmu(model: str = DEFAULT_MODEL) -> Path:
    """The project's FMU of ``model``, built from ``models/<model>`` (saying so) when missing."""
    return build_fmu(model, announce=True)


def extracted_fmu(fmu_path: Path) -> Path:
    """The FMU's files, extracted once into the per-user cache and shared by every plant.

    One folder per FMU content, ``extracted/<name>-<sha256 prefix>`` under
    :func:`fmu_build.build.cache_dir`, written under a temporary name and renamed into place: a
    concurrent process never sees a partial folder, and the extraction (about 20 ms) is paid
    once, not by every plant of every process.
    """
    digest = hashlib.sha256(fmu_path.read_bytes()).hexdigest()[:16]
    folder = cache_dir() / "extracted" / f"{fmu_path.stem}-{digest}"
    if folder.is_dir():
        return folder
    folder.parent.mkdir(parents=True, exist_ok=True)
    partial = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        extract(str(fmu_path), unzipdir=partial)
        partial.rename(folder)
    except OSError:
        if not folder.is_dir():  # else another process placed it first: theirs is the same
            raise
    except Exception as exc:  # fmpy raises bare Exceptions for a bad archive
        raise PlantError(f"{fmu_path}: cannot extract: {exc}") from exc
    finally:
        shutil.rmtree(partial, ignore_errors=True)  # nothing left once renamed
    return folder


class Plant:
    """One plant FMU, instantiated once (from its extraction in the cache), reset between runs.

    Parameters
    ----------
    fmu_path
        The .fmu file; the project's drive2mass FMU (built on first use) when None.
    instance_name
        Name given to fmi2Instantiate.
    """

    def __init__(self, fmu_path: Path | str | None = None, instance_name: str = "plant") -> None:
        self.fmu_path = Path(fmu_path) if fmu_path is not None else default_fmu()
        self.messages: list[str] = []
        if not self.fmu_path.is_file():
            raise PlantError(f"{self.fmu_path}: FMU file not found")
        if not zipfile.is_zipfile(self.fmu_path):
            raise PlantError(f"{self.fmu_path}: not an FMU (not a zip archive)")
        try:
            self.description = read_model_description(str(self.fmu_path), validate=False)
        except Exception as exc:  # fmpy raises bare Exceptions for every kind of bad archive
            raise PlantError(f"{self.fmu_path}: cannot read modelDescription.xml: {exc}") from exc
        if self.description.coSimulation is None:
            raise PlantError(f"{self.fmu_path}: the FMU does not support co-simulation")
        version = self.description.fmiVersion.split(".")[0]
        if version not in ("2", "3"):
            raise PlantError(
                f"{self.fmu_path}: FMI {self.description.fmiVersion}; the twin runs FMI 2.0 and "
                "FMI 3.0 co-simulation FMUs"
            )
        self.fmi_version = int(version)
        self.variables = {v.name: v for v in self.description.modelVariables}
        self._check_contract()
        self._unzip_dir = str(extracted_fmu(self.fmu_path))
        try:
            self.fmu = self._instantiate(instance_name)
        except Exception as exc:
            raise PlantError(
                f"{self.fmu_path}: cannot load or instantiate: {exc}{self._log()}"
            ) from exc
        self._fresh = True

    # ------------------------------------------------------------------ set-up

    def _check_contract(self) -> None:
        problems = []
        for name, causality in [(n, "input") for n in CONTRACT_INPUTS] + [
            (n, "output") for n in CONTRACT_OUTPUTS
        ]:
            variable = self.variables.get(name)
            if variable is None:
                problems.append(f"missing {causality} {name!r}")
            elif variable.causality != causality or variable.type != REAL_TYPES[self.fmi_version]:
                problems.append(f"{name!r} must be a {REAL_TYPES[self.fmi_version]} {causality}")
        if problems:
            raise PlantError(
                f"{self.fmu_path}: does not offer the plant contract: {'; '.join(problems)}"
            )

    def _instantiate(self, instance_name: str) -> FMU2Slave | FMU3Slave:
        """The version's slave, instantiated with a logger that keeps the FMU's messages."""

        def keep(category: bytes, message: bytes) -> None:
            self.messages.append(
                f"[{category.decode(errors='replace')}] {message.decode(errors='replace')}"
            )

        slave_type = FMU2Slave if self.fmi_version == 2 else FMU3Slave
        fmu = slave_type(
            guid=self.description.guid,
            unzipDirectory=self._unzip_dir,
            modelIdentifier=self.description.coSimulation.modelIdentifier,
            instanceName=instance_name,
        )
        if self.fmi_version == 3:
            fmu.instantiate(
                logMessage=lambda _env, _status, category, message: keep(category, message)
            )
            return fmu
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda _env, _instance, _status, category, message: keep(category, message)
        )
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(ctypes.byref(callbacks))
        self._callbacks = callbacks  # kept alive as long as the instance
        fmu.instantiate(callbacks=callbacks)
        return fmu

    def _log(self) -> str:
        return ("\nFMU log:\n  " + "\n  ".join(self.messages[-10:])) if self.messages else ""

    # ------------------------------------------------------------------ variables

    def value_reference(self, name: str) -> int:
        """Value reference of a variable; :class:`PlantError` names the FMU when it is missing."""
        variable = self.variables.get(name)
        if variable is None:
            raise PlantError(f"{self.fmu_path}: no variable named {name!r}")
        return variable.valueReference

    def parameter_names(self) -> list[str]:
        """Names of the FMU's parameters."""
        return [v.name for v in self.description.modelVariables if v.causality == "parameter"]

    def start_values(self) -> dict[str, float]:
        """Start values of the FMU's parameters, as declared in modelDescription.xml."""
        return {
            v.name: float(v.start)
            for v in self.description.modelVariables
            if v.causality == "parameter" and v.start is not None
        }

    # ------------------------------------------------------------------ runs

    def function_addresses(self) -> tuple[int, int, int]:
        """The addresses of the version's SetReal (fmi2SetReal, fmi3SetFloat64), DoStep and
        GetReal (fmi2GetReal, fmi3GetFloat64) C functions, for the compiled master."""
        dll = self.fmu.dll
        names = FMI_CALLS[self.fmi_version]
        return tuple(  # type: ignore[return-value]
            ctypes.cast(getattr(dll, names[what]), ctypes.c_void_p).value
            for what in ("set", "step", "get")
        )

    def set_reals(self, references: list[int], values: list[float]) -> None:
        """Set real (Float64) variables by value reference; PlantError on failure."""
        if self.fmi_version == 2:
            self.call("fmi2SetReal", self.fmu.setReal, references, values)
        else:
            self.call("fmi3SetFloat64", self.fmu.setFloat64, references, values)

    def get_reals(self, references: list[int]) -> list[float]:
        """Real (Float64) variables by value reference; PlantError on failure."""
        if self.fmi_version == 2:
            return self.call("fmi2GetReal", self.fmu.getReal, references)
        return self.call("fmi3GetFloat64", self.fmu.getFloat64, references)

    def do_step(self, t: float, h: float) -> None:
        """One communication step from ``t`` (s) of length ``h`` (s); PlantError on failure."""
        name = FMI_CALLS[self.fmi_version]["step"]
        self.call(name, self.fmu.doStep, t, h)

    def call(self, what: str, function, *args):
        """Call an fmpy method and turn any failure into :class:`PlantError` with the FMU's log."""
        try:
            return function(*args)
        except Exception as exc:
            raise PlantError(f"{self.fmu_path}: {what} failed: {exc}{self._log()}") from exc

    def start_run(
        self, parameters: Mapping[str, float] | None = None, start_time: float = 0.0
    ) -> None:
        """Reset the instance, apply parameters by name and initialise at ``start_time`` (s).

        Parameters
        ----------
        parameters
            Parameter values by FMU variable name; a name the FMU lacks raises PlantError.
        start_time
            Model time of the first communication point, s.
        """
        self.messages.clear()
        prefix = f"fmi{self.fmi_version}"
        if not self._fresh:
            self.call(f"{prefix}Reset", self.fmu.reset)
        self._fresh = False
        for name, value in (parameters or {}).items():
            variable = self.variables.get(name)
            if variable is None or variable.causality != "parameter":
                raise PlantError(
                    f"{self.fmu_path}: the FMU has no parameter named {name!r}; "
                    f"its parameters are {self.parameter_names()}"
                )
            if variable.type == INTEGER_TYPES[self.fmi_version]:
                if float(value) != int(value):
                    raise PlantError(
                        f"{self.fmu_path}: parameter {name!r} needs an integer, got {value}"
                    )
                set_integer = self.fmu.setInteger if self.fmi_version == 2 else self.fmu.setInt32
                self.call(f"setting {name}", set_integer, [variable.valueReference], [int(value)])
            else:
                self.set_reals([variable.valueReference], [float(value)])
        if self.fmi_version == 2:
            self.call("fmi2SetupExperiment", self.fmu.setupExperiment, None, start_time)
            self.call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)
        else:
            self.call(
                "fmi3EnterInitializationMode",
                self.fmu.enterInitializationMode,
                None,
                start_time,
            )
        self.call(f"{prefix}ExitInitializationMode", self.fmu.exitInitializationMode)

    def close(self) -> None:
        """Free the instance (the extracted files stay in the cache for the next plant)."""
        fmu = getattr(self, "fmu", None)
        if fmu is not None:
            fmu.freeInstance()
            self.fmu = None

    def __enter__(self) -> Plant:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
