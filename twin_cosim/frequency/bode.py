"""``twin bode``: a loop's frequency response measured on the twin, beside the linearised one.

The measurement (:mod:`twin_cosim.frequency.measurement`) runs the scenario's plant and
controller with the nonlinearities on (as a drive measures a machine) or off (the plant model's
card says which parameter values switch them off); the linearised response
(:mod:`twin_cosim.frequency.loops`) comes from the card's linear two-mass model at the same
plant parameters. Open loops get their margins from the measured data and, by python-control,
from the linearised loop.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.frequency.frf_file import coherence_drops, describe_drops, write_frf
from twin_cosim.frequency.loops import LinearLoops, speed_loop_of_plant
from twin_cosim.frequency.margins import Margins, margins_of_data, margins_of_system
from twin_cosim.frequency.measurement import (
    MeasurementSettings,
    default_amplitude,
    measure,
)
from twin_cosim.frequency.plots import plot_bode, plot_nyquist
from twin_cosim.frequency.response import PLANT_BAND, UNITS, FrequencyResponse
from twin_cosim.frequency.two_mass import TwoMass
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario

COHERENCE_FLOOR = 0.9  # where the report says the coherence drops
DEVIATION_BAND_HZ = (10.0, 500.0)  # measured against linearised, the plant's resonances within
EXCITATION_UNITS = {"plant": "A", "speed": "rad/s", "position": "m"}


@dataclass(frozen=True)
class BodeResult:
    """A measured response, its linearised counterpart and their margins.

    Attributes
    ----------
    scenario : Scenario
        The scenario measured (its controller set applied).
    how : MeasurementSettings
        The loop, excitation and operating point.
    nonlinear : bool
        Whether the nonlinearities were on.
    measured : FrequencyResponse
        The measurement.
    linearised : FrequencyResponse or None
        The linearised response at the measured lines; None when the card gives no linear model.
    margins : Margins or None
        Of the measured open loop; for the plant, of the speed loop made of the measured plant
        (all its lines, up to the Nyquist frequency) and the speed controller; None for a closed
        loop.
    linearised_margins : Margins or None
        The same of the linearised loop; None for a closed loop or without a linear model.
    amplitude : float
        RMS of the excitation, unit :data:`EXCITATION_UNITS` of the loop.
    wall_s : float
        Wall time of the measurement, s.
    """

    scenario: Scenario
    how: MeasurementSettings
    nonlinear: bool
    measured: FrequencyResponse
    linearised: FrequencyResponse | None
    margins: Margins | None
    linearised_margins: Margins | None
    amplitude: float
    wall_s: float

    def deviation(self) -> dict[str, float] | None:
        """Largest |measured / linearised| in dB and degrees over :data:`DEVIATION_BAND_HZ`."""
        if self.linearised is None:
            return None
        f = self.measured.frequency_hz
        band = (f >= DEVIATION_BAND_HZ[0]) & (f <= DEVIATION_BAND_HZ[1])
        ratio = self.measured.response[band] / self.linearised.response[band]
        return {
            "from_hz": DEVIATION_BAND_HZ[0],
            "to_hz": DEVIATION_BAND_HZ[1],
            "max_db": float(np.max(np.abs(20 * np.log10(np.abs(ratio))))),
            "max_deg": float(np.max(np.abs(np.degrees(np.angle(ratio))))),
        }

    def summary(self) -> dict[str, Any]:
        """The JSON summary: measured lists, margins, the linearised response, the set-up."""
        m = self.measured
        linear = self.linearised
        return {
            "scenario": str(self.scenario.source),
            "loop": m.loop,
            "kind": m.kind,
            "nonlinear": "on" if self.nonlinear else "off",
            "response": m.description,
            "unit": m.unit,
            "frequency_hz": m.frequency_hz.tolist(),
            "magnitude_db": m.magnitude_db.tolist(),
            "phase_deg": m.phase_deg.tolist(),
            "coherence": m.coherence.tolist(),
            "margins": None if self.margins is None else self.margins.as_dict(),
            "margins_of": None if self.margins is None else f"{_margins_loop(m.loop)} loop",
            "linearised": None
            if linear is None
            else {
                "magnitude_db": linear.magnitude_db.tolist(),
                "phase_deg": linear.phase_deg.tolist(),
                "margins": None
                if self.linearised_margins is None
                else self.linearised_margins.as_dict(),
            },
            "deviation": self.deviation(),
            "coherence_floor": COHERENCE_FLOOR,
            "coherence_drops": coherence_drops(m.frequency_hz, m.coherence, COHERENCE_FLOOR),
            "excitation": {
                "signal": "multisine, random phases, log-spaced lines",
                "rms": self.amplitude,
                "unit": EXCITATION_UNITS[m.loop],
                "lines": len(m.frequency_hz),
                "realisations": self.how.averages,
                "operating_speed_m_s": self.how.speed,
                "speed_noise_rad_s": self.how.speed_noise,
                "seed": self.how.seed,
            },
            "params": self.scenario.tuned.as_dict(),
            "wall_s": self.wall_s,
        }


def bode(
    scenario: Scenario, how: MeasurementSettings, nonlinear: bool, fmu: Path | None = None
) -> BodeResult:
    """Measure a loop of ``scenario`` on its plant (or ``fmu``) and linearise it.

    Raises
    ------
    PlantModelError
        With ``nonlinear`` off on a plant whose model card gives no linear model.
    """
    model = plant_model(scenario.model_name(fmu))
    parameters = dict(scenario.plant_parameters)
    if not nonlinear:
        if not model.nonlinear_off:
            raise ValueError(
                f"--nonlinear off: the card of plant model {model.name!r} does not say which "
                "parameters switch its nonlinearities off (linear.nonlinear_off)"
            )
        parameters |= model.nonlinear_off
    amplitude = how.amplitude or default_amplitude(how.loop, scenario.tuned, scenario.settings)
    with Plant(scenario.plant_fmu(fmu)) as plant:
        start = time.perf_counter()
        measured = measure(
            plant,
            scenario.tuned,
            scenario.settings,
            parameters,
            how,
            float(scenario.reference.position[0]),
        )
        wall = time.perf_counter() - start
    margins = _measured_margins(scenario, measured)
    if how.loop == "plant":  # the continuous plant, where the hold is divided out exactly enough
        measured = measured.below(PLANT_BAND * 0.5 / scenario.settings.speed_period)
    linear = None
    if model.two_mass:
        linear_plant = TwoMass.of_plant(model.name, parameters)
        linear = LinearLoops(linear_plant, scenario.tuned, scenario.settings)
    f = measured.frequency_hz
    return BodeResult(
        scenario=scenario,
        how=how,
        nonlinear=nonlinear,
        measured=measured,
        linearised=None
        if linear is None
        else FrequencyResponse(how.loop, how.kind, f, linear.response(how.loop, how.kind, f)),
        margins=margins,
        linearised_margins=None
        if linear is None or how.kind == "closed"
        else margins_of_system(linear.open_loop(_margins_loop(how.loop)), how.low_hz),
        amplitude=amplitude,
        wall_s=wall,
    )


def _margins_loop(loop: str) -> str:
    """The loop whose margins a measurement gives: the plant's are the speed loop's."""
    return "speed" if loop == "plant" else loop


def _measured_margins(scenario: Scenario, measured: FrequencyResponse) -> Margins | None:
    """Margins of a measured open loop (of the speed loop built on a measured plant)."""
    if measured.kind == "closed":
        return None
    loop = measured.response
    if measured.loop == "plant":
        loop = speed_loop_of_plant(
            scenario.tuned, scenario.settings, measured.frequency_hz, measured.response
        )
    return margins_of_data(measured.frequency_hz, loop)


def write_bode(result: BodeResult, out: Path, command: str) -> dict[str, str]:
    """Write ``frf.csv``, ``bode.png`` and, for an open loop, ``nyquist.png`` into ``out``.

    ``command`` is the command line that made the measurement (the files say it).
    """
    out.mkdir(parents=True, exist_ok=True)
    m = result.measured
    state = "nonlinearities " + ("on" if result.nonlinear else "off")
    comment = f"{command}: {m.description}, {UNITS[m.loop]} ({state})"
    files = {"frf": str(write_frf(out / "frf.csv", m, comment))}
    responses = {f"measured ({state})": m}
    if result.linearised is not None:
        responses["linearised"] = result.linearised
    title = f"{result.scenario.name}: {m.description}\n{command}"
    files["bode"] = str(
        plot_bode(responses, title, out / "bode.png", result.margins, COHERENCE_FLOOR)
    )
    if m.loop != "plant" and m.kind == "open":  # the plant is no loop: no -1 point
        files["nyquist"] = str(plot_nyquist(responses, title, out / "nyquist.png"))
    return files


def describe(result: BodeResult) -> list[str]:
    """The result in a few lines for a reader."""
    m = result.measured
    lines = [f"{m.description} ({m.unit}), {len(m.frequency_hz)} lines, {result.wall_s:.2f} s"]
    deviation = result.deviation()
    if deviation is not None:
        lines.append(
            f"measured against linearised, {deviation['from_hz']:g}-{deviation['to_hz']:g} Hz: "
            f"within {deviation['max_db']:.3g} dB and {deviation['max_deg']:.3g} deg"
        )
    lines.append(
        describe_drops(
            coherence_drops(m.frequency_hz, m.coherence, COHERENCE_FLOOR), COHERENCE_FLOOR
        )
    )
    loop = _margins_loop(m.loop)
    for label, margins in (("measured", result.margins), ("linearised", result.linearised_margins)):
        if margins is not None:
            lines.append(f"{loop} loop margins ({label}): {_margins_text(margins)}")
    return lines


def _margins_text(m: Margins) -> str:
    def number(value: float | None, unit: str) -> str:
        return "none" if value is None or not math.isfinite(value) else f"{value:.3g} {unit}"

    return (
        f"gain {number(m.gain_margin_db, 'dB')}, phase {number(m.phase_margin_deg, 'deg')} at "
        f"{number(m.crossover_hz, 'Hz')}, bandwidth {number(m.bandwidth_hz, 'Hz')}, "
        f"peak sensitivity {m.peak_sensitivity_db:.3g} dB"
    )
