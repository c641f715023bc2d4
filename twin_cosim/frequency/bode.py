"""``twin bode``: a loop's frequency response measured on the twin, beside the linearised one,
and the Bode and Nyquist figures of responses (PNG, matplotlib's Agg, imported to draw).

The measurement (:mod:`twin_cosim.frequency.measurement`) runs the scenario's plant and
controller with the nonlinearities on (as a drive measures a machine) or off (the plant model's
card says which parameter values switch them off); the linearised response
(:mod:`twin_cosim.frequency.linear`) comes from the card's linear two-mass model at the same
plant parameters. Every response of the speed and position loops (open, closed, sensitivity)
gets its loop's margins and closed-loop figures from the measured data (those read where the
coherence is below the floor withheld, :mod:`twin_cosim.frequency.margins`) and, by
python-control, from the linearised loop. The disturbance response gets the dynamic stiffness'
figures: its value at the lowest line and its minimum (:class:`StiffnessFigures`).
"""

from __future__ import annotations

import dataclasses
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
from twin_cosim.frequency.margins import (
    COHERENCE_FLOOR,
    Margins,
    dense_grid,
    margins_of_data,
    margins_of_system,
    open_loop_of,
)
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

DEVIATION_BAND_HZ = (10.0, 500.0)  # measured against linearised, the plant's resonances within
EXCITATION_UNITS = {"plant": "A", "speed": "rad/s", "position": "m", "disturbance": "N.m"}


@dataclass(frozen=True)
class StiffnessFigures:
    """What a servo engineer reads from a dynamic stiffness curve.

    Attributes
    ----------
    low_frequency_n_per_um : float or None
        |K| at the lowest line, N/um (an integral speed loop makes it grow without bound as
        the frequency falls); None when withheld.
    low_frequency_hz : float
        That line, Hz.
    minimum_n_per_um : float or None
        The smallest |K|, N/um (near the mechanical resonance); None when withheld.
    minimum_hz : float or None
        Where it lies, Hz.
    withheld : dict
        Figures read at or above a line whose coherence is below the floor (as
        :class:`~twin_cosim.frequency.margins.Margins`).
    """

    low_frequency_n_per_um: float | None
    low_frequency_hz: float
    minimum_n_per_um: float | None
    minimum_hz: float | None
    withheld: dict[str, dict[str, float]]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return dataclasses.asdict(self)


def stiffness_figures(
    frequency_hz: np.ndarray,
    stiffness: np.ndarray,
    coherence: np.ndarray | None = None,
    floor: float = COHERENCE_FLOOR,
) -> StiffnessFigures:
    """The figures of a dynamic stiffness (N/um, complex) at increasing frequencies (Hz); with
    ``coherence``, a figure read at or above a line below ``floor`` is withheld."""
    f = np.asarray(frequency_hz, dtype=np.float64)
    magnitude = np.abs(stiffness)
    i = int(np.argmin(magnitude))
    read = {"low_frequency_n_per_um": (0, magnitude[0]), "minimum_n_per_um": (i, magnitude[i])}
    withheld = {}
    if coherence is not None:
        for name, (line, value) in read.items():
            lowest = float(np.min(coherence[: line + 1]))
            if lowest < floor:
                withheld[name] = {
                    "value": float(value),
                    "frequency_hz": float(f[line]),
                    "lowest_coherence": lowest,
                    "floor": floor,
                }
    return StiffnessFigures(
        low_frequency_n_per_um=None
        if "low_frequency_n_per_um" in withheld
        else float(magnitude[0]),
        low_frequency_hz=float(f[0]),
        minimum_n_per_um=None if "minimum_n_per_um" in withheld else float(magnitude[i]),
        minimum_hz=None if "minimum_n_per_um" in withheld else float(f[i]),
        withheld=withheld,
    )


@dataclass(frozen=True)
class BodeResult:
    """A measured response, its linearised counterpart and their figures.

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
        Of the measured loop (its open loop from any of its responses); for the plant, of the
        speed loop made of the measured plant (all its lines, up to the Nyquist frequency) and
        the speed controller; None for the disturbance response.
    linearised_margins : Margins or None
        The same of the linearised loop; None without a linear model.
    stiffness : StiffnessFigures or None
        The dynamic stiffness' figures, measured (disturbance response only).
    linearised_stiffness : StiffnessFigures or None
        The same of the linearised cascade (its minimum on a dense grid).
    amplitude : float
        RMS of the excitation, unit :data:`EXCITATION_UNITS` of the loop.
    coherence_floor : float
        Figures read where the coherence is below it are withheld.
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
    stiffness: StiffnessFigures | None
    linearised_stiffness: StiffnessFigures | None
    amplitude: float
    coherence_floor: float
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
        """The JSON summary: measured lists, figures, the linearised response, the set-up."""
        m = self.measured
        linear = self.linearised
        floor = self.coherence_floor
        summary = {
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
            "coherence_floor": floor,
            "coherence_drops": coherence_drops(m.frequency_hz, m.coherence, floor),
            "excitation": {
                "signal": "multisine, random phases, log-spaced lines",
                "rms": self.amplitude,
                "unit": EXCITATION_UNITS[m.loop],
                "lines": len(m.frequency_hz),
                "realisations": self.how.averages,
                "operating_speed_m_s": self.how.operating_speed(self.scenario.settings),
                "speed_noise_rad_s": self.how.speed_noise,
                "seed": self.how.seed,
            },
            "params": self.scenario.tuned.as_dict(),
            "wall_s": self.wall_s,
        }
        if self.stiffness is not None:
            summary["stiffness_n_per_um"] = np.abs(m.response).tolist()
            summary["stiffness"] = self.stiffness.as_dict()
            if linear is not None and self.linearised_stiffness is not None:
                summary["linearised"]["stiffness_n_per_um"] = np.abs(linear.response).tolist()
                summary["linearised"]["stiffness"] = self.linearised_stiffness.as_dict()
        return summary


def bode(
    scenario: Scenario,
    how: MeasurementSettings,
    nonlinear: bool,
    fmu: Path | None = None,
    coherence_floor: float = COHERENCE_FLOOR,
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
    margins = _measured_margins(scenario, measured, coherence_floor)
    if how.loop == "plant":  # the continuous plant, where the hold is divided out exactly enough
        measured = measured.below(PLANT_BAND * 0.5 / scenario.settings.speed_period)
    linear = None
    if model.two_mass:
        linear_plant = TwoMass.of_plant(model.name, parameters)
        linear = LinearLoops(linear_plant, scenario.tuned, scenario.settings)
    f = measured.frequency_hz
    disturbance = how.loop == "disturbance"
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
        if linear is None or disturbance
        else margins_of_system(linear.open_loop(_margins_loop(how.loop)), how.low_hz),
        stiffness=stiffness_figures(f, measured.response, measured.coherence, coherence_floor)
        if disturbance
        else None,
        linearised_stiffness=None
        if linear is None or not disturbance
        else linearised_stiffness(linear, f),
        amplitude=amplitude,
        coherence_floor=coherence_floor,
        wall_s=wall,
    )


def linearised_stiffness(linear: LinearLoops, frequency_hz: np.ndarray) -> StiffnessFigures:
    """The linearised cascade's stiffness figures: at the lowest measured line (Hz) and its
    minimum on a dense grid over the measured band."""
    low = float(frequency_hz[0])
    grid = np.concatenate([[low], dense_grid(low, float(frequency_hz[-1]))[1:]])
    return stiffness_figures(grid, linear.dynamic_stiffness(grid))


def _margins_loop(loop: str) -> str:
    """The loop whose margins a measurement gives: the plant's are the speed loop's."""
    return "speed" if loop == "plant" else loop


def _measured_margins(
    scenario: Scenario, measured: FrequencyResponse, floor: float
) -> Margins | None:
    """Margins of a measured loop (of the speed loop built on a measured plant); figures read
    where the coherence is below ``floor`` withheld."""
    if measured.loop == "disturbance":
        return None
    loop = open_loop_of(measured.kind, measured.response)
    if measured.loop == "plant":
        loop = speed_loop_of_plant(
            scenario.tuned, scenario.settings, measured.frequency_hz, measured.response
        )
    return margins_of_data(measured.frequency_hz, loop, measured.coherence, floor)


def write_bode(result: BodeResult, out: Path, command: str, plots: bool = True) -> dict[str, str]:
    """Write ``frf.csv`` and (``plots``) ``bode.png`` and, for an open loop, ``nyquist.png``
    into ``out``; for the disturbance response ``stiffness.png`` in place of ``bode.png``.

    ``command`` is the command line that made the measurement (the files say it).
    """
    out.mkdir(parents=True, exist_ok=True)
    m = result.measured
    state = "nonlinearities " + ("on" if result.nonlinear else "off")
    comment = f"{command}: {m.description}, {UNITS[m.loop]} ({state})"
    files = {"frf": str(write_frf(out / "frf.csv", m, comment))}
    if not plots:
        return files
    responses = {f"measured ({state})": m}
    if result.linearised is not None:
        responses["linearised"] = result.linearised
    title = f"{result.scenario.name}: {m.description}\n{command}"
    if m.loop == "disturbance":
        files["stiffness"] = str(plot_stiffness(result, title, out / "stiffness.png"))
        return files
    files["bode"] = str(
        plot_bode(
            responses,
            title,
            out / "bode.png",
            result.margins,
            result.coherence_floor,
            f"{_margins_loop(m.loop)} loop, measured: ",
        )
    )
    if m.loop != "plant" and m.kind == "open":  # the plant is no loop: no -1 point
        files["nyquist"] = str(plot_nyquist(responses, title, out / "nyquist.png"))
    return files


def describe(result: BodeResult) -> list[str]:
    """The result in a few lines for a reader."""
    m = result.measured
    floor = result.coherence_floor
    lines = [f"{m.description} ({m.unit}), {len(m.frequency_hz)} lines, {result.wall_s:.2f} s"]
    deviation = result.deviation()
    if deviation is not None:
        lines.append(
            f"measured against linearised, {deviation['from_hz']:g}-{deviation['to_hz']:g} Hz: "
            f"within {deviation['max_db']:.3g} dB and {deviation['max_deg']:.3g} deg"
        )
    lines.append(describe_drops(coherence_drops(m.frequency_hz, m.coherence, floor), floor))
    loop = _margins_loop(m.loop)
    for label, margins in (("measured", result.margins), ("linearised", result.linearised_margins)):
        if margins is not None:
            lines.append(f"{loop} loop ({label}): {margins_text(margins)}")
            lines.extend(f"  {note}" for note in withheld_notes(margins.withheld))
    for label, figures in (
        ("measured", result.stiffness),
        ("linearised", result.linearised_stiffness),
    ):
        if figures is not None:
            lines.append(f"dynamic stiffness ({label}): {stiffness_text(figures)}")
            lines.extend(f"  {note}" for note in withheld_notes(figures.withheld))
    return lines


def _number(value: float | None, unit: str, digits: int = 3) -> str:
    """A figure with its unit, or 'withheld' / 'none'."""
    if value is None or not math.isfinite(value):
        return "none"
    return f"{value:.{digits}g} {unit}"


def margins_text(m: Margins) -> str:
    """Margins and closed-loop figures on one line (withheld ones named so)."""

    def figure(name: str, value: float | None, at: float | None = None) -> str:
        if name in m.withheld:
            return "withheld"
        text = _number(value, FIGURE_NAMES[name][1])
        return text if at is None or value is None else f"{text} at {_number(at, 'Hz', 4)}"

    return (
        f"gain margin {figure('gain_margin_db', m.gain_margin_db, m.phase_crossover_hz)}, "
        f"phase margin {figure('phase_margin_deg', m.phase_margin_deg, m.crossover_hz)}, "
        f"bandwidth {figure('bandwidth_hz', m.bandwidth_hz)}, resonance peak "
        f"{figure('resonance_peak_db', m.resonance_peak_db, m.resonance_peak_hz)}, peak "
        f"sensitivity {figure('peak_sensitivity_db', m.peak_sensitivity_db, m.peak_sensitivity_hz)}"
    )


def stiffness_text(s: StiffnessFigures) -> str:
    """The stiffness figures on one line."""
    low = (
        "withheld"
        if s.low_frequency_n_per_um is None
        else _number(s.low_frequency_n_per_um, "N/um", 4)
    )
    minimum = (
        "withheld"
        if s.minimum_n_per_um is None
        else (f"{_number(s.minimum_n_per_um, 'N/um', 4)} at {_number(s.minimum_hz, 'Hz', 4)}")
    )
    return f"{low} at {s.low_frequency_hz:.3g} Hz, minimum {minimum}"


FIGURE_NAMES = {  # field: (what a reader calls it, unit)
    "gain_margin_db": ("gain margin", "dB"),
    "phase_margin_deg": ("phase margin", "deg"),
    "bandwidth_hz": ("bandwidth", "Hz"),
    "resonance_peak_db": ("resonance peak", "dB"),
    "peak_sensitivity_db": ("peak sensitivity", "dB"),
    "low_frequency_n_per_um": ("low-frequency stiffness", "N/um"),
    "minimum_n_per_um": ("minimum stiffness", "N/um"),
}


def withheld_notes(withheld: Mapping[str, Mapping[str, float]]) -> list[str]:
    """Why each withheld figure is withheld, one line each."""
    return [
        f"{FIGURE_NAMES[name][0]} withheld: read as {_as_read(name, w)}, "
        f"above a line of coherence {w['lowest_coherence']:.2f} (floor {w['floor']:g})"
        for name, w in withheld.items()
    ]


def _as_read(name: str, withheld: Mapping[str, float]) -> str:
    """A withheld figure's value as read, with its unit and (unless it is one) its frequency."""
    unit = FIGURE_NAMES[name][1]
    where = "" if unit == "Hz" else f" at {withheld['frequency_hz']:.4g} Hz"
    return f"{withheld['value']:.3g} {unit}{where}"


def plot_bode(
    responses: Mapping[str, FrequencyResponse],
    title: str,
    path: Path,
    margins: Margins | None = None,
    coherence_floor: float | None = None,
    margins_label: str = "",
) -> Path:
    """Magnitude, phase and (where measured) coherence against frequency; returns ``path``.

    ``responses`` by label: measured ones (with a coherence) drawn as points, computed ones as
    lines; ``margins`` are written above the phase (withheld ones said so) and marked: the
    crossover of an open loop, the bandwidth of a closed one, the peak of a sensitivity;
    ``coherence_floor`` draws that level; ``margins_label`` says whose the margins are.
    """
    from twin_cosim.plots import save_figure, stacked_axes

    measured = any(r.coherence is not None for r in responses.values())
    rows, ratios = (3, [3, 2, 1]) if measured else (2, [3, 2])
    fig, axes = stacked_axes(rows, (9, 3 * rows), ratios)
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
    if margins is not None:
        _mark_margins(axes, margins, first.kind, margins_label)
    fig.suptitle(_wrapped(title), fontsize=9)
    axes[0].legend(fontsize=8)
    return save_figure(fig, axes, path)


def _mark_margins(axes, margins: Margins, kind: str, label: str) -> None:  # type: ignore[no-untyped-def]
    """The figures as the magnitude axis' title, and the frequency they are read at marked on the
    magnitude and phase axes: the crossover (open), the bandwidth (closed) or the peak
    sensitivity (sensitivity)."""
    level, at = {
        "open": (0.0, margins.crossover_hz),
        "closed": (-3.0103, margins.bandwidth_hz),
        "sensitivity": (margins.peak_sensitivity_db, margins.peak_sensitivity_hz),
    }[kind]
    if at is not None:
        for ax in axes[:2]:
            ax.axvline(at, color="grey", lw=0.8, ls=":")
        axes[0].axhline(level, color="grey", lw=0.8, ls=":")
    text = label + margins_text(margins) + withheld_line(margins.withheld)
    axes[0].set_title(
        _wrapped(text, 130), fontsize=8, color="tab:red" if margins.withheld else "black"
    )


def withheld_line(withheld: Mapping[str, Mapping[str, float]]) -> str:
    """The withheld figures as read, on a line of their own for a figure ('' when none)."""
    if not withheld:
        return ""
    floor = next(iter(withheld.values()))["floor"]
    read = ", ".join(
        f"{FIGURE_NAMES[name][0]} {_as_read(name, w)} ({w['lowest_coherence']:.2f})"
        for name, w in withheld.items()
    )
    return f"\nwithheld, read above a line of coherence below {floor:g} (lowest): {read}"


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


def plot_stiffness(result: BodeResult, title: str, path: Path) -> Path:
    """The dynamic stiffness |K| (N/um, log scale), its phase and the coherence against
    frequency, measured (points) and linearised (line), the minima marked; returns ``path``."""
    from twin_cosim.plots import save_figure, stacked_axes

    fig, axes = stacked_axes(3, (9, 9), [3, 2, 1])
    state = "nonlinearities " + ("on" if result.nonlinear else "off")
    curves = [(f"measured ({state})", result.measured, result.stiffness)]
    if result.linearised is not None:
        curves.append(("linearised", result.linearised, result.linearised_stiffness))
    phases = _phases([r for _, r, _ in curves])
    for (label, r, figures), phase in zip(curves, phases, strict=True):
        measured = r.coherence is not None
        style = {"marker": ".", "ms": 3, "lw": 0.6} if measured else {"lw": 1.2}
        (line,) = axes[0].loglog(r.frequency_hz, np.abs(r.response), label=label, **style)
        axes[1].semilogx(r.frequency_hz, phase, **style)
        if measured:
            axes[2].semilogx(r.frequency_hz, r.coherence, **style)
        if figures is not None and figures.minimum_n_per_um is not None:
            axes[0].plot(
                [figures.minimum_hz],
                [figures.minimum_n_per_um],
                "v",
                color=line.get_color(),
                ms=8,
                label=f"minimum, {label}: {figures.minimum_n_per_um:.3g} N/um at "
                f"{figures.minimum_hz:.3g} Hz",
            )
    axes[2].axhline(result.coherence_floor, color="tab:red", lw=0.8, ls="--", label="floor")
    axes[0].set_ylabel("dynamic stiffness |K| [N/um]")
    axes[1].set_ylabel("phase [deg]")
    axes[2].set_ylabel("coherence")
    axes[2].set_ylim(-0.05, 1.05)
    axes[2].set_xlabel("frequency [Hz]")
    fig.suptitle(_wrapped(title), fontsize=9)
    if result.stiffness is not None:
        withheld = result.stiffness.withheld
        text = "measured: " + stiffness_text(result.stiffness) + withheld_line(withheld)
        axes[0].set_title(_wrapped(text, 130), fontsize=8, color="tab:red" if withheld else "black")
    axes[0].legend(fontsize=8)
    axes[2].legend(fontsize=8, loc="lower left")
    return save_figure(fig, axes, path)


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
