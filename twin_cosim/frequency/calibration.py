"""``twin calibrate --frf``: the two-mass parameters from a plant FRF, as ``plant.yaml``; the FRF
files it reads (and ``twin bode`` writes), and the fit.

The FRF file is read with its checks, its low-coherence bands masked; the two-mass model is fitted
to the rest and its J_M, J_L, f_1, D_1 and F_V written as a plant parameter file
(:mod:`twin_cosim.scenario.plant_parameters`) with where each value came from. The FRF is motor
speed over the drive's torque setpoint, so the inertias are those that the drive's torque constant
sees. Another calibration of the same machine (``--beside``, e.g. the ``plant.yaml`` of ``twin
diagnose``, the time-domain calibration) is reported beside it, parameter by parameter.

FRF files: a plant's measured frequency response as CSV. Layout (``#`` lines are comments; a
header row names the columns)::

    # twin bode reference1 --loop plant: motor speed over torque setpoint, rad/s per N.m
    f,magnitude_db,phase_deg,coherence
    1.953125,-18.7,-91.2,0.998
    ...

- ``f``: frequency, Hz, > 0 and increasing (also read as ``f_hz``, ``frequency``,
  ``frequency_hz``, ``freq``, ``freq_hz``);
- the response, motor speed over motor torque (eq. (3)), as ``magnitude_db`` [dB re 1 rad/s per
  N.m] and ``phase_deg`` [deg] (also ``magnitude``, ``mag_db``, ``gain_db``; ``phase``), or as
  ``real`` and ``imag`` [rad/s per N.m] (also ``re``/``im``, ``imaginary``); both forms may be
  given when they agree;
- ``coherence`` (optional), in [0, 1] (also ``gamma2``, ``coh``).

Refused, with the file, the column and the frequency named: a missing column, a value that is
missing (an empty cell) or not a finite number, frequencies that are not positive or not
increasing, a gap in the frequencies (a spacing more than :data:`GAP_FACTOR` times both of its
neighbours'), a zero magnitude, a coherence outside [0, 1], magnitude/phase and real/imaginary
that disagree, and too few lines left. Lines whose coherence lies below the floor are masked
(left out of a fit), and the masked bands are reported.

The fit: J_M, J_L, f_1, D_1, viscous friction, and the drive's delay and current-loop lag.
Model: motor speed over motor torque, eq. (3) with viscous friction F_V on the load
(:meth:`~twin_cosim.frequency.linear.TwoMass.speed_per_torque`), times
exp(-j w tau) / (1 + j w tau_i) for what the measurement holds of the drive: a delay tau (its
sampling and computation) and a first-order current loop tau_i. Fitted in the log of
the ratio model / measurement, whose real part is the magnitude error (in nepers) and imaginary
part the phase error (rad), so that every line counts alike at any level; each line is weighted
by its coherence gamma^2 / (1 - gamma^2) (its signal-to-noise ratio, capped), or equally
without one. The parameters are fitted in logarithms (J_M, J_L, f_1, D_1) and in natural
scales (F_V over J w_01, tau and tau_i in ms), with bounds that keep them physical (the delay
and the lag are not negative); the fit starts from what the curve shows (:func:`first_guess`)
with several damping ratios and keeps the best.

The delay and the lag are reported only where the data identify them: a value counts when it
is more than twice its standard error (from the fit's Jacobian and residual, the other
parameters held) and the phase it
adds at the highest fitted line exceeds twice the fit's RMS phase error (what the data can
tell from a misfit). Otherwise it is "not identified" (null in the JSON, with the bound below
which it lies), whatever tiny number the optimiser stopped at; the design model uses it as
fitted (a small value changes nothing there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from twin_cosim.frequency.linear import TwoMass
from twin_cosim.frequency.measurement import FrequencyResponse
from twin_cosim.measured import MeasuredDataError
from twin_cosim.plant_model import plant_model
from twin_cosim.scenario import Scenario
from twin_cosim.scenario.plant_parameters import (
    PlantParameters,
    fitted_plant,
    read_plant_parameters,
    write_plant_parameters,
)

ALIASES = {
    "f": ("f", "f_hz", "frequency", "frequency_hz", "freq", "freq_hz"),
    "magnitude_db": ("magnitude_db", "magnitude", "mag_db", "gain_db"),
    "phase_deg": ("phase_deg", "phase"),
    "real": ("real", "re"),
    "imag": ("imag", "imaginary", "im"),
    "coherence": ("coherence", "gamma2", "coh"),
}
GAP_FACTOR = 4.0
MIN_LINES = 8
AGREEMENT_DB, AGREEMENT_DEG = 0.1, 1.0
DEFAULT_COHERENCE_FLOOR = 0.8
MAX_WEIGHT = 1.0e3  # the largest coherence weight, gamma^2 / (1 - gamma^2)
DAMPING_STARTS = (0.05, 0.15, 0.4)
DELAY_BOUND_MS = 20.0
LAG_BOUND_MS = 20.0
DRIVE_TERMS = ("delay_s", "current_lag_s")  # what the measurement holds of the drive
FITTED = (
    "motor_inertia",
    "load_inertia",
    "resonance_frequency",
    "damping_ratio",
    "viscous_friction",
)
FITTED_UNITS = {
    "motor_inertia": "kg.m2",
    "load_inertia": "kg.m2",
    "resonance_frequency": "Hz",
    "damping_ratio": "1",
    "viscous_friction": "N.m.s/rad",
}


@dataclass(frozen=True)
class FrfData:
    """A checked FRF file.

    Attributes
    ----------
    source : Path
        The file.
    frequency_hz : numpy.ndarray
        Frequencies, Hz, increasing.
    response : numpy.ndarray
        Motor speed over motor torque, rad/s per N.m, complex.
    coherence : numpy.ndarray or None
        Coherence per line, when the file gives it.
    used : numpy.ndarray
        Lines at or above the coherence floor (bool).
    masked_bands : list of tuple
        (from, to, lowest coherence) of each run of masked lines, Hz, Hz, 1.
    """

    source: Path
    frequency_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray | None
    used: np.ndarray
    masked_bands: list[tuple[float, float, float]]

    def notes(self, floor: float) -> list[str]:
        """The masked bands in words (one line each)."""
        return [
            f"{self.source}: column coherence below {floor:g} from {low:g} to {high:g} Hz "
            f"(lowest {lowest:.3g}): masked"
            for low, high, lowest in self.masked_bands
        ]


def write_frf(path: Path, response: FrequencyResponse, comment: str) -> Path:
    """Write ``response`` as an FRF file (magnitude, phase, coherence) under a comment line."""
    frame = pd.DataFrame(
        {
            "f": response.frequency_hz,
            "magnitude_db": response.magnitude_db,
            "phase_deg": response.phase_deg,
        }
    )
    if response.coherence is not None:
        frame["coherence"] = response.coherence
    with open(path, "w") as out:
        out.write(f"# {comment}\n")
        frame.to_csv(out, index=False, float_format="%.10g")
    return path


def _columns(path: Path, frame: pd.DataFrame) -> dict[str, str]:
    """Canonical column name -> the file's column, for those present."""
    by_name = {str(c).strip().lower(): c for c in frame.columns}
    found = {}
    for canonical, names in ALIASES.items():
        present = [by_name[n] for n in names if n in by_name]
        if len(present) > 1:
            raise MeasuredDataError(f"{path}: columns {present} all mean {canonical}; keep one")
        if present:
            found[canonical] = present[0]
    if "f" not in found:
        raise MeasuredDataError(
            f"{path}: no frequency column (f [Hz]); columns: {list(frame.columns)}"
        )
    polar = {"magnitude_db", "phase_deg"} <= set(found)
    cartesian = {"real", "imag"} <= set(found)
    if not (polar or cartesian):
        raise MeasuredDataError(
            f"{path}: expected columns magnitude_db [dB] and phase_deg [deg], or real and imag; "
            f"columns: {list(frame.columns)}"
        )
    return found


def _numbers(path: Path, frame: pd.DataFrame, column: str, f: np.ndarray | None) -> np.ndarray:
    """A column as finite floats; a MeasuredDataError names a missing or bad value by its
    frequency."""
    text = frame[column]
    values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=np.float64)
    for row in np.flatnonzero(~np.isfinite(values)):
        raw = text.iloc[row]
        at = f"f = {f[row]:g} Hz" if f is not None and np.isfinite(f[row]) else "frequency"
        what = (
            "a missing value (a gap)"
            if pd.isna(raw) or not str(raw).strip()
            else f"{str(raw).strip()!r}, not a finite number"
        )
        raise MeasuredDataError(f"{path}: column {column}: {what} at {at} (data row {row + 1})")
    return values


def _check_frequencies(path: Path, column: str, f: np.ndarray) -> None:
    """Positive, increasing, without gaps."""
    if f[0] <= 0:
        raise MeasuredDataError(f"{path}: column {column}: frequency {f[0]:g} Hz is not above 0")
    steps = np.diff(f)
    bad = np.flatnonzero(steps <= 0)
    if len(bad):
        i = int(bad[0])
        raise MeasuredDataError(
            f"{path}: column {column}: frequencies not increasing at f = {f[i + 1]:g} Hz "
            f"(data row {i + 2}, after {f[i]:g} Hz)"
        )
    for i in range(len(steps)):
        neighbours = [steps[j] for j in (i - 1, i + 1) if 0 <= j < len(steps)]
        if neighbours and all(steps[i] > GAP_FACTOR * n for n in neighbours):
            raise MeasuredDataError(
                f"{path}: column {column}: a gap, no line between {f[i]:g} and {f[i + 1]:g} Hz "
                f"(a spacing over {GAP_FACTOR:g} times its neighbours'); give the band or "
                "cut the file before it"
            )


def _response(path: Path, columns: dict[str, str], values: dict[str, np.ndarray], f) -> np.ndarray:
    """The complex response from magnitude/phase or real/imaginary (checked to agree)."""
    polar = cartesian = None
    if "magnitude_db" in values:
        polar = 10 ** (values["magnitude_db"] / 20) * np.exp(1j * np.radians(values["phase_deg"]))
    if "real" in values:
        cartesian = values["real"] + 1j * values["imag"]
        zero = np.flatnonzero(cartesian == 0)
        if len(zero):
            raise MeasuredDataError(
                f"{path}: columns {columns['real']}, {columns['imag']}: zero response at "
                f"f = {f[zero[0]]:g} Hz"
            )
    if polar is not None and cartesian is not None:
        ratio = cartesian / polar
        off = np.flatnonzero(
            (np.abs(20 * np.log10(np.abs(ratio))) > AGREEMENT_DB)
            | (np.abs(np.degrees(np.angle(ratio))) > AGREEMENT_DEG)
        )
        if len(off):
            raise MeasuredDataError(
                f"{path}: columns magnitude_db/phase_deg and real/imag disagree at "
                f"f = {f[off[0]]:g} Hz; give one form"
            )
    return cartesian if cartesian is not None else polar


def read_frf(path: Path | str, coherence_floor: float = DEFAULT_COHERENCE_FLOOR) -> FrfData:
    """Read and check an FRF file; lines with coherence below ``coherence_floor`` are masked.

    Raises
    ------
    MeasuredDataError
        Naming the file, the column and the frequency (see the module's list).
    """
    path = Path(path)
    if not path.is_file():
        raise MeasuredDataError(f"{path}: FRF file not found")
    try:
        frame = pd.read_csv(
            path, comment="#", dtype=str, skipinitialspace=True, keep_default_na=False
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise MeasuredDataError(f"{path}: not a CSV file with a header row: {exc}") from None
    columns = _columns(path, frame)
    f = _numbers(path, frame, columns["f"], None)
    if len(f) < MIN_LINES:
        raise MeasuredDataError(f"{path}: {len(f)} lines; a fit needs at least {MIN_LINES}")
    _check_frequencies(path, columns["f"], f)
    values = {k: _numbers(path, frame, c, f) for k, c in columns.items() if k != "f"}
    response = _response(path, columns, values, f)
    coherence = values.get("coherence")
    used = np.ones(len(f), dtype=bool)
    bands: list[tuple[float, float, float]] = []
    if coherence is not None:
        outside = np.flatnonzero((coherence < 0) | (coherence > 1))
        if len(outside):
            i = int(outside[0])
            raise MeasuredDataError(
                f"{path}: column {columns['coherence']}: {coherence[i]:g} at f = {f[i]:g} Hz "
                "is outside [0, 1]"
            )
        used = coherence >= coherence_floor
        bands = _runs(f, coherence, ~used)
        if used.sum() < MIN_LINES:
            raise MeasuredDataError(
                f"{path}: column {columns['coherence']}: only {int(used.sum())} lines at or "
                f"above the coherence floor {coherence_floor:g}; a fit needs {MIN_LINES}"
            )
    return FrfData(path, f, response, coherence, used, bands)


def _runs(f: np.ndarray, coherence: np.ndarray, masked: np.ndarray) -> list:
    """(from Hz, to Hz, lowest coherence) of each run of masked lines."""
    runs = []
    start = None
    for i, flag in enumerate([*masked, False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            runs.append((float(f[start]), float(f[i - 1]), float(coherence[start:i].min())))
            start = None
    return runs


def coherence_drops(
    frequency_hz: np.ndarray, coherence: np.ndarray, floor: float
) -> list[dict[str, float]]:
    """Where a measured coherence lies below ``floor``: bands (Hz) and their lowest value."""
    return [
        {"from_hz": low, "to_hz": high, "lowest": lowest}
        for low, high, lowest in _runs(frequency_hz, coherence, coherence < floor)
    ]


def describe_drops(drops: list[dict[str, float]], floor: float) -> str:
    """The bands of :func:`coherence_drops` in words."""
    if not drops:
        return f"coherence at or above {floor:g} at every line"
    bands = ", ".join(
        f"{d['from_hz']:.4g}-{d['to_hz']:.4g} Hz (lowest {d['lowest']:.2f})"
        if not math.isclose(d["from_hz"], d["to_hz"])
        else f"{d['from_hz']:.4g} Hz ({d['lowest']:.2f})"
        for d in drops
    )
    return f"coherence below {floor:g} at {bands}"


@dataclass(frozen=True)
class TwoMassFit:
    """The fitted two-mass plant and how well it fits.

    Attributes
    ----------
    plant : TwoMass
        J_M, J_L, coupling and viscous friction (torque constant 1: the FRF is per N.m).
    delay_s : float
        Fitted delay, s.
    lag_s : float
        Fitted current-loop time constant, s.
    rms_db : float
        Weighted RMS magnitude error over the fitted lines, dB.
    rms_deg : float
        Weighted RMS phase error, degrees.
    lines : int
        Lines fitted.
    resolution_s : dict
        Per drive term (``delay_s``, ``current_lag_s``): the smallest value the data identify,
        s (twice the standard error, or what adds twice the RMS phase error at the highest
        line, whichever is larger).
    """

    plant: TwoMass
    delay_s: float
    lag_s: float
    rms_db: float
    rms_deg: float
    lines: int
    resolution_s: dict[str, float]

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The fitted model at ``frequency_hz`` (Hz), delay included, rad/s per N.m."""
        return _drive(self.plant, self.delay_s, self.lag_s, np.asarray(frequency_hz, float))

    def parameters(self) -> dict[str, float]:
        """The FMU parameters it gives (drive2mass names, SI units)."""
        return {
            "motor_inertia": float(self.plant.motor_inertia),
            "load_inertia": float(self.plant.load_inertia),
            "resonance_frequency": float(self.plant.antiresonance_hz),
            "damping_ratio": float(self.plant.damping_ratio),
            "viscous_friction": float(self.plant.viscous_friction),
        }

    def drive_terms(self) -> dict[str, float | None]:
        """The delay and the current lag (s) where identified, else None."""
        fitted = {"delay_s": self.delay_s, "current_lag_s": self.lag_s}
        return {
            name: value if value > self.resolution_s[name] else None
            for name, value in fitted.items()
        }

    def not_identified(self) -> dict[str, str]:
        """Why each unidentified drive term is not reported, in words."""
        return {
            name: f"below {self.resolution_s[name] * 1e6:.3g} us, what these data resolve"
            for name, value in self.drive_terms().items()
            if value is None
        }

    def drive_text(self) -> str:
        """The delay and the current lag for a reader (us, or not identified)."""
        names = {"delay_s": "delay", "current_lag_s": "current lag"}
        words = []
        for name, value in self.drive_terms().items():
            if value is None:
                words.append(
                    f"{names[name]} not identified (below {self.resolution_s[name] * 1e6:.3g} us)"
                )
            else:
                words.append(f"{names[name]} {value * 1e6:.3g} us")
        return ", ".join(words)


def _plant(theta: np.ndarray, scale: float) -> tuple[TwoMass, float, float]:
    """The plant, delay (s) and lag (s) of the fit's parameter vector."""
    j_m, j_l, f_1, d_1 = (float(v) for v in np.exp(theta[:4]))
    viscous = float(theta[4]) * scale
    plant = TwoMass.from_paper(j_m, j_l, f_1, d_1, viscous_friction=viscous)
    return plant, float(theta[5]) * 1e-3, float(theta[6]) * 1e-3


def _drive(plant: TwoMass, delay: float, lag: float, frequency_hz: np.ndarray) -> np.ndarray:
    """Eq. (3) with viscous friction, the delay and the lag, rad/s per N.m."""
    s = 2j * np.pi * frequency_hz
    return plant.speed_per_torque(frequency_hz) * np.exp(-s * delay) / (1.0 + s * lag)


def _model(theta: np.ndarray, scale: float, frequency_hz: np.ndarray) -> np.ndarray:
    """The fitted model's response at ``frequency_hz`` (rad/s per N.m, complex)."""
    return _drive(*_plant(theta, scale), frequency_hz)


def first_guess(frequency_hz: np.ndarray, response: np.ndarray) -> tuple[float, float, float]:
    """J_M, J_L (kg.m2) and f_1 (Hz) from the curve w |H|: its low and high asymptotes
    1 / (J_M + J_L) and 1 / J_M, its minimum (antiresonance) and the maximum above it."""
    g = 2 * np.pi * frequency_hz * np.abs(response)
    n = max(2, len(g) // 10)
    total = 1.0 / np.median(g[:n])
    low = int(np.argmin(g[n:-n])) + n if len(g) > 2 * n + 2 else int(np.argmin(g))
    high = low + int(np.argmax(g[low:]))
    ratio = (frequency_hz[high] / frequency_hz[low]) ** 2
    if not 1.05 < ratio < 100.0:  # no clear pair: from the asymptotes alone
        ratio = min(max(total * np.median(g[-n:]), 1.05), 100.0)
    j_m = total / ratio
    return j_m, total - j_m, float(frequency_hz[low])


def fit_two_mass(
    frequency_hz: np.ndarray, response: np.ndarray, coherence: np.ndarray | None = None
) -> TwoMassFit:
    """Fit the two-mass model to a plant FRF (motor speed over motor torque).

    Parameters
    ----------
    frequency_hz
        Frequencies of the lines to fit, Hz.
    response
        The measured response, rad/s per N.m, complex.
    coherence
        gamma^2 per line, or None (equal weights).
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    h = np.asarray(response, dtype=np.complex128)
    if coherence is None:
        weights = np.ones(len(f))
    else:
        gamma = np.clip(coherence, 0.0, 1.0)
        weights = np.minimum(gamma / np.maximum(1.0 - gamma, 1.0 / MAX_WEIGHT), MAX_WEIGHT)
    root = np.sqrt(weights / weights.mean())
    j_m, j_l, f_1 = first_guess(f, h)
    scale = (j_m + j_l) * 2 * np.pi * f_1  # N.m.s/rad: viscous friction in these units

    def residual(theta: np.ndarray) -> np.ndarray:
        error = np.log(_model(theta, scale, f) / h)
        return np.concatenate([root * error.real, root * error.imag])

    lower = np.log([j_m / 20, j_l / 20, f[0] / 2, 1e-3]).tolist()
    lower += [0.0, 0.0, 0.0]
    upper = np.log([j_m * 20, j_l * 20, f[-1] * 2, 5.0]).tolist()
    upper += [10.0, DELAY_BOUND_MS, LAG_BOUND_MS]
    best = None
    for damping in DAMPING_STARTS:
        start = np.array([*np.log([j_m, j_l, f_1, damping]), 0.0, 0.0, 0.0])
        start = np.clip(start, np.array(lower) + 1e-9, np.array(upper) - 1e-9)
        found = least_squares(residual, start, bounds=(lower, upper), x_scale="jac")
        if best is None or found.cost < best.cost:
            best = found
    theta = np.where(best.active_mask < 0, lower, best.x)  # held at a lower bound: the bound
    plant, delay, lag = _plant(theta, scale)
    error = np.log(_model(theta, scale, f) / h)
    rms_deg = float(np.degrees(np.sqrt(np.average(error.imag**2, weights=weights))))
    return TwoMassFit(
        plant=plant,
        delay_s=delay,
        lag_s=lag,
        rms_db=float(np.sqrt(np.average(error.real**2, weights=weights)) * 20 / math.log(10)),
        rms_deg=rms_deg,
        lines=len(f),
        resolution_s=_drive_resolution(best, float(f[-1]), rms_deg),
    )


def _drive_resolution(found: Any, top_hz: float, rms_deg: float) -> dict[str, float]:
    """The smallest delay and current lag (s) the fit resolves: twice the standard error of
    each (the others held: near zero a delay and a lag change the phase alike, so only their
    sum is defined and the joint covariance is singular), or the value that adds twice the
    fit's RMS phase error at the highest line (``top_hz``), whichever is larger."""
    jacobian = found.jac
    dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
    curvature = np.sum(jacobian**2, axis=0)
    standard_ms = np.sqrt(2.0 * found.cost / dof / np.maximum(curvature, 1e-300))
    phase = math.radians(2.0 * rms_deg)  # rad at the highest line
    w_top = 2 * math.pi * top_hz
    return {
        "delay_s": max(2.0 * standard_ms[5] * 1e-3, phase / w_top),
        "current_lag_s": max(2.0 * standard_ms[6] * 1e-3, math.tan(min(phase, 1.5)) / w_top),
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
                    "unit": FITTED_UNITS[name],
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
            **self.fit.drive_terms(),
            "not_identified": self.fit.not_identified(),
            "rms_db": self.fit.rms_db,
            "rms_deg": self.fit.rms_deg,
            "lines_fitted": self.fit.lines,
            "lines_masked": int((~self.frf.used).sum()),
            "masked_bands_hz": [list(band[:2]) for band in self.frf.masked_bands],
            "beside": None if self.beside is None else str(self.beside.source),
            "table": self.table(),
        }

    def responses(self) -> dict[str, FrequencyResponse]:
        """The FRF file's response and the fitted model's at its lines, by label (to draw)."""
        f = self.frf.frequency_hz
        return {
            "FRF file": FrequencyResponse(
                "plant", "open", f, self.frf.response, self.frf.coherence
            ),
            "fitted two-mass model": FrequencyResponse("plant", "open", f, self.fit.response(f)),
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
    plant_model(model).require_parameters(FITTED, "twin calibrate --frf fits the parameters")
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
    plant = fitted_plant(
        model,
        values,
        source,
        command,
        frf=str(frf.source),
        **fit.drive_terms(),
        masked_bands_hz=[list(band[:2]) for band in frf.masked_bands],
    )
    nominal = {**plant_model(model).start_values(), **scenario.plant_parameters}
    other = None if beside is None else read_plant_parameters(beside, model)
    return Calibration(frf, fit, plant, {n: nominal[n] for n in FITTED}, other)


def write_calibration_files(calibration: Calibration, out: Path) -> dict[str, str]:
    """Write ``plant.yaml`` and ``calibration.md``; their paths (``plant``, ``table``)."""
    out.mkdir(parents=True, exist_ok=True)
    files = {"plant": str(write_plant_parameters(out / "plant.yaml", calibration.plant))}
    (out / "calibration.md").write_text(calibration.markdown())
    files["table"] = str(out / "calibration.md")
    return files
