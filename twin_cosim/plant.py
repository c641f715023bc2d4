"""Access to a plant FMU: load once, instantiate once, reset and parametrise per run.

Any FMI 2.0 co-simulation FMU that offers the plant contract runs in the twin:

- inputs ``current_cmd`` [A] and ``disturbance_torque`` [N.m];
- outputs ``motor_angle`` [rad], ``motor_speed`` [rad/s], ``load_position`` [m] (the linear
  scale's reading) and ``load_speed`` [m/s].

Every fmi2 call is checked; a failure raises :class:`PlantError` with the FMU's logged messages.
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
from fmpy.logging import addLoggerProxy

from fmu_build.build import DEFAULT_MODEL, build_fmu, cache_dir

# The plant contract, the one place of its names: the co-simulation master sets the inputs and
# reads the outputs in these orders.
CONTRACT_INPUTS = ("current_cmd", "disturbance_torque")
CONTRACT_OUTPUTS = ("motor_angle", "motor_speed", "load_position", "load_speed")


class PlantError(RuntimeError):
    """The plant FMU is missing, corrupt, lacks the plant contract, or an fmi2 call failed."""


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
        self.variables = {v.name: v for v in self.description.modelVariables}
        self._check_contract()
        self._unzip_dir = str(extracted_fmu(self.fmu_path))
        self._callbacks = self._make_callbacks()
        try:
            self.fmu = FMU2Slave(
                guid=self.description.guid,
                unzipDirectory=self._unzip_dir,
                modelIdentifier=self.description.coSimulation.modelIdentifier,
                instanceName=instance_name,
            )
            self.fmu.instantiate(callbacks=self._callbacks)
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
            elif variable.causality != causality or variable.type != "Real":
                problems.append(f"{name!r} must be a Real {causality}")
        if problems:
            raise PlantError(
                f"{self.fmu_path}: does not offer the plant contract: {'; '.join(problems)}"
            )

    def _make_callbacks(self) -> fmi2CallbackFunctions:
        def log(_env, instance, status, category, message) -> None:
            self.messages.append(
                f"[{category.decode(errors='replace')}] {message.decode(errors='replace')}"
            )

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(ctypes.byref(callbacks))
        return callbacks

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
        if not self._fresh:
            self.call("fmi2Reset", self.fmu.reset)
        self._fresh = False
        for name, value in (parameters or {}).items():
            variable = self.variables.get(name)
            if variable is None or variable.causality != "parameter":
                raise PlantError(
                    f"{self.fmu_path}: the FMU has no parameter named {name!r}; "
                    f"its parameters are {self.parameter_names()}"
                )
            if variable.type == "Integer":
                if float(value) != int(value):
                    raise PlantError(
                        f"{self.fmu_path}: parameter {name!r} needs an integer, got {value}"
                    )
                self.call(
                    f"setting {name}", self.fmu.setInteger, [variable.valueReference], [int(value)]
                )
            else:
                self.call(
                    f"setting {name}", self.fmu.setReal, [variable.valueReference], [float(value)]
                )
        self.call("fmi2SetupExperiment", self.fmu.setupExperiment, None, start_time)
        self.call("fmi2EnterInitializationMode", self.fmu.enterInitializationMode)
        self.call("fmi2ExitInitializationMode", self.fmu.exitInitializationMode)

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
