"""FRF files: a plant's measured frequency response as CSV, written and read with checks.

Layout (``#`` lines are comments; a header row names the columns)::

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
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from twin_cosim.frequency.response import FrequencyResponse

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


class FrfFileError(ValueError):
    """An FRF file is refused; the message names the file, the column and the frequency."""


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
            raise FrfFileError(f"{path}: columns {present} all mean {canonical}; keep one")
        if present:
            found[canonical] = present[0]
    if "f" not in found:
        raise FrfFileError(f"{path}: no frequency column (f [Hz]); columns: {list(frame.columns)}")
    polar = {"magnitude_db", "phase_deg"} <= set(found)
    cartesian = {"real", "imag"} <= set(found)
    if not (polar or cartesian):
        raise FrfFileError(
            f"{path}: expected columns magnitude_db [dB] and phase_deg [deg], or real and imag; "
            f"columns: {list(frame.columns)}"
        )
    return found


def _numbers(path: Path, frame: pd.DataFrame, column: str, f: np.ndarray | None) -> np.ndarray:
    """A column as finite floats; FrfFileError names a missing or bad value by its frequency."""
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
        raise FrfFileError(f"{path}: column {column}: {what} at {at} (data row {row + 1})")
    return values


def _check_frequencies(path: Path, column: str, f: np.ndarray) -> None:
    """Positive, increasing, without gaps."""
    if f[0] <= 0:
        raise FrfFileError(f"{path}: column {column}: frequency {f[0]:g} Hz is not above 0")
    steps = np.diff(f)
    bad = np.flatnonzero(steps <= 0)
    if len(bad):
        i = int(bad[0])
        raise FrfFileError(
            f"{path}: column {column}: frequencies not increasing at f = {f[i + 1]:g} Hz "
            f"(data row {i + 2}, after {f[i]:g} Hz)"
        )
    for i in range(len(steps)):
        neighbours = [steps[j] for j in (i - 1, i + 1) if 0 <= j < len(steps)]
        if neighbours and all(steps[i] > GAP_FACTOR * n for n in neighbours):
            raise FrfFileError(
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
            raise FrfFileError(
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
            raise FrfFileError(
                f"{path}: columns magnitude_db/phase_deg and real/imag disagree at "
                f"f = {f[off[0]]:g} Hz; give one form"
            )
    return cartesian if cartesian is not None else polar


def read_frf(path: Path | str, coherence_floor: float = DEFAULT_COHERENCE_FLOOR) -> FrfData:
    """Read and check an FRF file; lines with coherence below ``coherence_floor`` are masked.

    Raises
    ------
    FrfFileError
        Naming the file, the column and the frequency (see the module's list).
    """
    path = Path(path)
    if not path.is_file():
        raise FrfFileError(f"{path}: FRF file not found")
    try:
        frame = pd.read_csv(
            path, comment="#", dtype=str, skipinitialspace=True, keep_default_na=False
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise FrfFileError(f"{path}: not a CSV file with a header row: {exc}") from None
    columns = _columns(path, frame)
    f = _numbers(path, frame, columns["f"], None)
    if len(f) < MIN_LINES:
        raise FrfFileError(f"{path}: {len(f)} lines; a fit needs at least {MIN_LINES}")
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
            raise FrfFileError(
                f"{path}: column {columns['coherence']}: {coherence[i]:g} at f = {f[i]:g} Hz "
                "is outside [0, 1]"
            )
        used = coherence >= coherence_floor
        bands = _runs(f, coherence, ~used)
        if used.sum() < MIN_LINES:
            raise FrfFileError(
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
