"""``twin bode``: a loop's frequency response measured on the twin, beside the linearised one,
and the Bode and Nyquist figures of responses (PNG, matplotlib's Agg, imported to draw).

The measurement (:mod:`twin_cosim.frequency.measurement`) runs the scenario's plant and
controller with the nonlinearities on (as a drive measures a machine) or off (the plant model's
card says which parameter values switch them off); the linearised response
(:mod:`twin_cosim.frequency.linear`) comes from the card's linear two-mass model at the same
plant parameters. Open loops get their margins from the measured data and, by python-control,
from the linearised loop.
"""

from __future__ import annotations

import math
import textwrap
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.frequency.calibration import coherence_drops, describe_drops, write_frf
from twin_cosim.frequency.linear import LinearLoops, TwoMass, speed_loop_of_plant
from twin_cosim.frequency.margins import Margins, margins_of_data, margins_of_system
from twin_cosim.frequency.measurement import (
    PLANT_BAND,
    UNITS,
    FrequencyResponse,
    MeasurementSettings,
    default_amplitude,
    measure,
)
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


def plot_bode(
    responses: Mapping[str, FrequencyResponse],
    title: str,
    path: Path,
    margins: Margins | None = None,
    coherence_floor: float | None = None,
) -> Path:
    """Magnitude, phase and (where measured) coherence against frequency; returns ``path``.

    ``responses`` by label: measured ones (with a coherence) drawn as points, computed ones as
    lines; ``margins`` marks the crossover and phase margin; ``coherence_floor`` draws that
    level.
    """
    plt = _pyplot()
    measured = any(r.coherence is not None for r in responses.values())
    rows, ratios = (3, [3, 2, 1]) if measured else (2, [3, 2])
    fig, axes = plt.subplots(rows, 1, figsize=(9, 3 * rows), sharex=True, height_ratios=ratios)
    phases = _phases(list(responses.values()))
    for i, (label, r) in enumerate(responses.items()):
        style = {"marker": ".", "ms": 3, "lw": 0.6} if r.coherence is not None else {"lw": 1.2}
        axes[0].semilogx(r.frequency_hz, r.magnitude_db, label=label, **style)
        axes[1].semilogx(r.frequency_hz, phases[i], **style)
        if r.coherence is not None:
            axes[2].semilogx(r.frequency_hz, r.coherence, label=label, **style)
    first = next(iter(responses.values()))
    unit = "" if first.unit == "1" else f" re 1 {first.unit}"
    axes[0].set_ylabel(f"magnitude [dB{unit}]")
    axes[1].set_ylabel("phase [deg]")
    axes[-1].set_xlabel("frequency [Hz]")
    if measured:
        axes[2].set_ylabel("coherence")
        axes[2].set_ylim(-0.05, 1.05)
    if measured and coherence_floor is not None:
        axes[2].axhline(coherence_floor, color="tab:red", lw=0.8, ls="--", label="floor")
    if margins is not None and margins.crossover_hz is not None:
        for ax in axes[:2]:
            ax.axvline(margins.crossover_hz, color="grey", lw=0.8, ls=":")
        axes[0].axhline(0.0, color="grey", lw=0.8, ls=":")
        axes[1].set_title(
            f"phase margin {margins.phase_margin_deg:.1f} deg at {margins.crossover_hz:.1f} Hz"
            + (
                ""
                if margins.gain_margin_db is None
                else f", gain margin {margins.gain_margin_db:.1f} dB at "
                f"{margins.phase_crossover_hz:.0f} Hz"
            ),
            fontsize=9,
        )
    axes[0].set_title(_wrapped(title), fontsize=9)
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(True, which="both", lw=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _pyplot():  # type: ignore[no-untyped-def]
    """matplotlib's pyplot on the Agg backend, imported when a figure is drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _wrapped(title: str, width: int = 110) -> str:
    """A title's lines wrapped at ``width`` characters (a command line can be long)."""
    return "\n".join(textwrap.fill(line, width) for line in title.splitlines())


def _phases(responses: list[FrequencyResponse]) -> list[np.ndarray]:
    """Unwrapped phases (deg); the first shifted by whole turns to lie nearest the second's
    (a measurement whose low lines are noise can unwrap a turn away)."""
    phases = [np.degrees(np.unwrap(np.angle(r.response))) for r in responses]
    if len(phases) > 1 and len(phases[0]) == len(phases[1]):
        turns = np.round(np.median(phases[1] - phases[0]) / 360.0)
        phases[0] = phases[0] + 360.0 * turns
    return phases


def plot_nyquist(responses: Mapping[str, FrequencyResponse], title: str, path: Path) -> Path:
    """The Nyquist plot of open loops near -1 (the unit circle and -1 marked); returns ``path``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    for i, (label, r) in enumerate(responses.items()):
        style = {"marker": ".", "ms": 3, "lw": 0.6} if i == 0 else {"lw": 1.2}
        ax.plot(r.response.real, r.response.imag, label=label, **style)
    circle = np.exp(1j * np.linspace(0, 2 * np.pi, 200))
    ax.plot(circle.real, circle.imag, color="grey", lw=0.6, ls=":")
    ax.plot([-1], [0], "x", color="tab:red", ms=9, label="-1")
    ax.set_xlim(-3, 1.5)
    ax.set_ylim(-3, 1.5)
    ax.set_aspect("equal")
    ax.set_xlabel("real")
    ax.set_ylabel("imaginary")
    ax.set_title(_wrapped(title, 80), fontsize=8)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
