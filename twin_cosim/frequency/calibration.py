"""``twin calibrate --frf``: the two-mass parameters from a plant FRF, as ``plant.yaml``.

The FRF file (:mod:`twin_cosim.frequency.frf_file`) is read with its checks, its low-coherence
bands masked; the two-mass model is fitted to the rest (:mod:`twin_cosim.frequency.fit`) and
its J_M, J_L, f_1, D_1 and F_V written as a plant parameter file
(:mod:`twin_cosim.scenario.plant_file`) with where each value came from. The FRF is motor speed
over the drive's torque setpoint, so the inertias are those that the drive's torque constant
sees. Another calibration of the same machine (``--beside``, e.g. the ``plant.yaml`` of
``twin diagnose``, the time-domain calibration) is reported beside it, parameter by parameter.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin_cosim.frequency.fit import TwoMassFit, fit_two_mass
from twin_cosim.frequency.frf_file import FrfData
from twin_cosim.frequency.plots import plot_bode
from twin_cosim.frequency.response import FrequencyResponse
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.plant_file import (
    PlantParameters,
    read_plant_parameters,
    write_plant_parameters,
)
from twin_cosim.versions import versions

FITTED = (
    "motor_inertia",
    "load_inertia",
    "resonance_frequency",
    "damping_ratio",
    "viscous_friction",
)
UNITS = {
    "motor_inertia": "kg.m2",
    "load_inertia": "kg.m2",
    "resonance_frequency": "Hz",
    "damping_ratio": "1",
    "viscous_friction": "N.m.s/rad",
}


@dataclass(frozen=True)
class Calibration:
    """A fit of a plant FRF and the plant file it gives.

    Attributes
    ----------
    frf : FrfData
        The checked FRF file.
    fit : TwoMassFit
        The fit to its unmasked lines.
    plant : PlantParameters
        The plant parameter file's content.
    nominal : dict
        The scenario's values of the fitted parameters.
    beside : PlantParameters or None
        Another calibration of the same machine, reported beside.
    """

    frf: FrfData
    fit: TwoMassFit
    plant: PlantParameters
    nominal: dict[str, float]
    beside: PlantParameters | None

    def table(self) -> list[dict[str, Any]]:
        """Per fitted parameter: nominal, FRF fit, the other calibration (its value, or None)."""
        rows = []
        for name in FITTED:
            other = None if self.beside is None else self.beside.parameters.get(name)
            rows.append(
                {
                    "parameter": name,
                    "unit": UNITS[name],
                    "nominal": self.nominal[name],
                    "frf_fit": self.plant.parameters[name],
                    "beside": other,
                }
            )
        return rows

    def summary(self) -> dict[str, Any]:
        """JSON-ready: the table, the fit's quality, the masked bands."""
        return {
            "frf": str(self.frf.source),
            "parameters": self.plant.parameters,
            "delay_s": self.fit.delay_s,
            "current_lag_s": self.fit.lag_s,
            "rms_db": self.fit.rms_db,
            "rms_deg": self.fit.rms_deg,
            "lines_fitted": self.fit.lines,
            "lines_masked": int((~self.frf.used).sum()),
            "masked_bands_hz": [list(band[:2]) for band in self.frf.masked_bands],
            "beside": None if self.beside is None else str(self.beside.source),
            "table": self.table(),
        }

    def markdown(self) -> str:
        """The table as Markdown."""
        other = "" if self.beside is None else f" | {self.beside.source}"
        lines = [
            f"| parameter | unit | nominal | FRF fit{other} |",
            "|---|---|---|---|" + ("---|" if self.beside else ""),
        ]
        for row in self.table():
            cells = [
                row["parameter"],
                row["unit"],
                f"{row['nominal']:.4g}",
                f"{row['frf_fit']:.4g}",
            ]
            if self.beside is not None:
                cells.append("(nominal)" if row["beside"] is None else f"{row['beside']:.4g}")
            lines.append("| " + " | ".join(cells) + " |")
        return "\n".join(lines) + "\n"


def calibrate(
    scenario: Scenario,
    frf: FrfData,
    command: str,
    beside: Path | None = None,
) -> Calibration:
    """Fit the scenario's plant to ``frf``.

    Raises
    ------
    ValueError
        When the scenario's plant model has no two-mass parameters to fit.
    """
    model = scenario.model_name()
    known = plant_model(model).parameters
    missing = [name for name in FITTED if name not in known]
    if missing:
        raise ValueError(
            f"twin calibrate --frf fits the two-mass parameters {list(FITTED)}; plant model "
            f"{model!r} has no {missing}"
        )
    fit = fit_two_mass(
        frf.frequency_hz[frf.used],
        frf.response[frf.used],
        None if frf.coherence is None else frf.coherence[frf.used],
    )
    values = fit.parameters()
    source = (
        f"fitted to the plant FRF {frf.source} (twin calibrate): eq. (3) with viscous friction, "
        f"a delay and a current lag, {fit.lines} lines, RMS error {fit.rms_db:.3g} dB and "
        f"{fit.rms_deg:.3g} deg"
    )
    plant = PlantParameters(
        model=model,
        parameters=values,
        provenance={name: {"source": source} for name in values},
        created_by={
            "command": command,
            "version": versions()["twin-cosim"],
            "frf": str(frf.source),
            "delay_s": fit.delay_s,
            "current_lag_s": fit.lag_s,
            "masked_bands_hz": [list(band[:2]) for band in frf.masked_bands],
        },
    )
    nominal = {**plant_model(model).start_values(), **scenario.plant_parameters}
    other = None if beside is None else read_plant_parameters(beside, model)
    return Calibration(frf, fit, plant, {n: nominal[n] for n in FITTED}, other)


def write_calibration_files(calibration: Calibration, out: Path) -> dict[str, str]:
    """Write ``plant.yaml``, ``calibration.md`` and ``fit.png`` (FRF against the fit, titled
    with the command that made the calibration)."""
    out.mkdir(parents=True, exist_ok=True)
    files = {"plant": str(write_plant_parameters(out / "plant.yaml", calibration.plant))}
    (out / "calibration.md").write_text(calibration.markdown())
    files["table"] = str(out / "calibration.md")
    frf = calibration.frf
    f = frf.frequency_hz
    fitted = calibration.fit.response(f)
    responses = {
        "FRF file": FrequencyResponse("plant", "open", f, frf.response, frf.coherence),
        "fitted two-mass model": FrequencyResponse("plant", "open", f, fitted),
    }
    title = f"{frf.source}: the two-mass fit\n{calibration.plant.created_by['command']}"
    files["plot"] = str(plot_bode(responses, title, out / "fit.png"))
    return files
