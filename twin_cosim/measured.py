"""Measured runs: files of a real (or virtual) axis, their checks, and their match to a scenario.

CSV (the project's format): ``t`` [s], ``x_ref`` [m], ``x`` [m] (measured load position),
``current`` [A]; optional ``motor_speed`` [rad/s]; extra columns are ignored.

EMPS benchmark .mat files (as published, Janot, Gautier, Brunot 2019): ``t`` [s], ``qg``
(reference, m), ``qm`` (motor position in load units, m), ``vir`` (drive command, V) and the
scalars ``gtau`` [N/V], ``kp`` [1/s], ``kv`` [V/(m/s)]; the validation run also holds ``pulses_N``
(a signal of its record, N). ``current`` then holds the drive command vir in V.

A run's samples are a :class:`~twin_cosim.run_record.RunRecord` (a unit per column). Time must be
strictly increasing and regular. Every problem gets an error naming the file, the column and
what was expected, or, where the data can still be used, an explicit warning that the report
repeats.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord

REQUIRED = ("t", "x_ref", "x", "current")
OPTIONAL = ("motor_speed",)
SIGNAL_UNITS = {"t": "s", "x_ref": "m", "x": "m", "current": "A", "motor_speed": "rad/s"}
REGULARITY_TOLERANCE = 1e-3  # relative jitter of the sample period
MIN_SAMPLES = 100
UNIT_FACTORS = {1e3: "mm instead of m", 1e6: "um instead of m"}


def _signal(name: str, doc: str) -> property:
    """A signal of a run's record as an attribute of the run (the column itself, a view)."""
    return property(lambda run: run.record[name], doc=doc)


class MeasuredDataError(ValueError):
    """A measured run cannot be used; the message names the file, the column and the problem."""


@dataclass(frozen=True)
class MeasuredRun:
    """One measured run on a regular time grid.

    Attributes
    ----------
    source : str
        File it came from.
    record : RunRecord
        The samples: ``t`` [s], ``x_ref`` and ``x`` (reference and measured carriage position,
        m), ``current`` (current command, A; the drive command in V for an EMPS run), optionally
        ``motor_speed`` [rad/s] and further signals of the file (e.g. EMPS ``pulses_N``, N).
    warnings : list of str
        Problems that did not stop the diagnosis.
    scalars : dict
        Numbers the file holds besides its signals (e.g. EMPS ``gtau``, ``kp``, ``kv``).
    """

    source: str
    record: RunRecord
    warnings: list[str] = field(default_factory=list)
    scalars: dict[str, float] = field(default_factory=dict)

    @classmethod
    def from_signals(
        cls,
        source: str,
        signals: Mapping[str, np.ndarray],
        units: Mapping[str, str] | None = None,
        scalars: Mapping[str, float] | None = None,
    ) -> MeasuredRun:
        """A run of ``signals`` by name (``t``, ``x_ref``, ``x``, ``current`` and any further
        ones), in :data:`SIGNAL_UNITS` unless ``units`` names another."""
        known = {name: unit for name, unit in SIGNAL_UNITS.items() if name in signals}
        record = RunRecord.from_columns(signals, {**known, **(units or {})})
        return cls(source, record, scalars=dict(scalars or {}))

    t = _signal("t", "Sample times, s.")
    x_ref = _signal("x_ref", "Reference carriage position, m.")
    x = _signal("x", "Measured carriage position, m.")
    current = _signal("current", "Current command, A (the drive command, V, of an EMPS run).")

    @property
    def motor_speed(self) -> np.ndarray | None:
        """Measured motor speed, rad/s (None when the file has none)."""
        return self.record.get("motor_speed")

    @property
    def period(self) -> float:
        """Sample period, s."""
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    def select(self, mask: np.ndarray) -> MeasuredRun:
        """The samples where ``mask`` is True (same source, warnings and scalars)."""
        return MeasuredRun(self.source, self.record.rows(mask), self.warnings, self.scalars)

    def with_signals(self, signals: Mapping[str, np.ndarray]) -> MeasuredRun:
        """The run with ``signals`` (by name, one value per sample) in place of its own."""
        return MeasuredRun(
            self.source, self.record.with_columns(signals), self.warnings, self.scalars
        )


def read_measured_csv(path: Path | str) -> MeasuredRun:
    """Read and check a measured-run CSV.

    Raises
    ------
    MeasuredDataError
        On an unreadable file, missing columns, non-numeric or non-finite values (rows named),
        non-monotonic or irregular time, or too few samples.
    """
    import pandas as pd  # a CSV run only: pandas stays off the start of other commands

    path = Path(path)
    try:
        table = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as CSV: {exc}") from exc
    missing = [c for c in REQUIRED if c not in table.columns]
    if missing:
        raise MeasuredDataError(
            f"{path}: missing column(s) {missing}; expected t [s], x_ref [m], x [m], current [A] "
            f"(optional motor_speed [rad/s]), found {list(table.columns)}"
        )
    columns = {}
    for name in REQUIRED + tuple(c for c in OPTIONAL if c in table.columns):
        values = pd.to_numeric(table[name], errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            rows = ", ".join(str(r + 2) for r in bad[:5])  # +2: header line and 1-based rows
            raise MeasuredDataError(
                f"{path}: column {name!r} has {len(bad)} missing, non-numeric or non-finite "
                f"value(s) (file lines {rows}{', ...' if len(bad) > 5 else ''}); "
                "gaps must be filled"
            )
        columns[name] = values
    run = MeasuredRun.from_signals(str(path), columns)
    check_time(run)
    return run


EMPS_SIGNALS = {"t": "t", "qg": "x_ref", "qm": "x", "vir": "current"}
EMPS_SCALARS = ("gtau", "kp", "kv")


def _numeric(path: Path, name: str, value: object) -> np.ndarray:
    """A .mat variable as a flat float64 array; MeasuredDataError naming it otherwise."""
    try:
        values = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        values = np.empty(0)
    if values.size == 0:
        raise MeasuredDataError(
            f"{path}: variable {name!r} is not numeric (got {np.asarray(value).dtype} data); "
            "expected numbers"
        )
    return values


def read_emps_mat(path: Path | str) -> MeasuredRun:
    """Read an EMPS benchmark .mat file as it is published (with or without ``pulses_N``).

    Raises
    ------
    MeasuredDataError
        On an unreadable file, a missing variable, signals of different lengths or non-finite
        values.
    """
    from scipy.io import loadmat

    path = Path(path)
    try:
        data = loadmat(str(path))
    except (OSError, ValueError, NotImplementedError) as exc:
        raise MeasuredDataError(f"{path}: cannot read as a MATLAB file: {exc}") from exc
    missing = [name for name in EMPS_SIGNALS if name not in data]
    if missing:
        raise MeasuredDataError(
            f"{path}: missing variable(s) {missing}; an EMPS file holds t, qg, qm, vir"
        )
    signals = {}
    for name, role in EMPS_SIGNALS.items():
        values = _numeric(path, name, data[name])
        if not np.all(np.isfinite(values)):
            raise MeasuredDataError(f"{path}: variable {name!r} has non-finite values")
        signals[role] = values
    if len({len(v) for v in signals.values()}) != 1:
        raise MeasuredDataError(f"{path}: t, qg, qm and vir must have the same length")
    scalars = {
        name: float(_numeric(path, name, data[name])[0]) for name in EMPS_SCALARS if name in data
    }
    if "pulses_N" in data:
        pulses = _numeric(path, "pulses_N", data["pulses_N"])
        if pulses.shape != signals["t"].shape or not np.all(np.isfinite(pulses)):
            raise MeasuredDataError(f"{path}: pulses_N must be finite and as long as t")
        signals["pulses_N"] = pulses
    run = MeasuredRun.from_signals(str(path), signals, {"current": "V", "pulses_N": "N"}, scalars)
    check_time(run)
    return run


def read_measured(path: Path | str) -> MeasuredRun:
    """Read a measured run: .csv (the project's format) or .mat (EMPS benchmark)."""
    path = Path(path)
    if not path.is_file():
        raise MeasuredDataError(f"{path}: file not found")
    readers = {".csv": read_measured_csv, ".mat": read_emps_mat}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise MeasuredDataError(
            f"{path}: unknown measured-run type {path.suffix!r}; expected .csv or .mat"
        )
    return reader(path)


def check_time(run: MeasuredRun) -> None:
    """Strictly increasing, regular time with enough samples; MeasuredDataError otherwise."""
    t = run.t
    if len(t) < MIN_SAMPLES:
        raise MeasuredDataError(
            f"{run.source}: only {len(t)} samples; at least {MIN_SAMPLES} needed"
        )
    steps = np.diff(t)
    if np.any(steps <= 0):
        first = int(np.flatnonzero(steps <= 0)[0])
        raise MeasuredDataError(
            f"{run.source}: column 't' must increase strictly; t[{first + 1}] = {t[first + 1]} s "
            f"follows t[{first}] = {t[first]} s"
        )
    period = run.period
    jitter = np.abs(steps - period).max() / period
    if jitter > REGULARITY_TOLERANCE:
        where = int(np.argmax(np.abs(steps - period)))
        raise MeasuredDataError(
            f"{run.source}: column 't' is irregular: step {steps[where]:.6g} s at "
            f"t = {t[where]:.6g} s "
            f"against a mean period of {period:.6g} s (gaps or jitter; resample to a regular grid)"
        )


def _scale_mismatch(measured: np.ndarray, expected: np.ndarray) -> str | None:
    span = np.ptp(expected)
    if span == 0:
        return None
    ratio = np.ptp(measured) / span
    for factor, meaning in UNIT_FACTORS.items():
        if abs(ratio / factor - 1) < 0.05:
            return meaning
    return None


def check_against_reference(run: MeasuredRun, reference: ReferenceGrid) -> None:
    """The run must follow the scenario's reference (same motion, units of m, within its time).

    Raises
    ------
    MeasuredDataError
        When ``x_ref`` or ``x`` looks scaled by 1000 (mm instead of m), the run lasts longer
        or shorter than the reference (within two samples), or ``x_ref`` differs from the
        scenario's reference.
    """
    if run.t[-1] > reference.duration + 2 * run.period or run.t[0] < -run.period:
        raise MeasuredDataError(
            f"{run.source}: the run spans {run.t[0]:.4g} to {run.t[-1]:.4g} s, outside the "
            f"scenario's reference (0 to {reference.duration:.4g} s)"
        )
    if run.t[-1] < reference.duration - 2 * run.period or run.t[0] > run.period:
        raise MeasuredDataError(
            f"{run.source}: the run spans {run.t[0]:.4g} to {run.t[-1]:.4g} s, shorter than "
            f"the scenario's reference (0 to {reference.duration:.4g} s): a run cut short "
            "leaves out motion the scenario needs; record the whole reference"
        )
    expected = np.interp(run.t, reference.time, reference.position)
    for column, values in (("x_ref", run.x_ref), ("x", run.x)):
        meaning = _scale_mismatch(values, expected)
        if meaning:
            raise MeasuredDataError(
                f"{run.source}: column {column!r} looks like {meaning} (its range is "
                f"{np.ptp(values):.4g} against the scenario's {np.ptp(expected):.4g} m)"
            )
    tolerance = 1e-6 + 1e-3 * np.ptp(expected)  # m
    deviation = np.abs(run.x_ref - expected)
    if deviation.max() > tolerance:
        at = int(np.argmax(deviation))
        raise MeasuredDataError(
            f"{run.source}: column 'x_ref' does not match the scenario's reference: "
            f"{deviation[at] * 1e6:.4g} um apart at t = {run.t[at]:.4g} s (tolerance "
            f"{tolerance * 1e6:.3g} um); is it a run of another scenario?"
        )


def current_warnings(run: MeasuredRun, current_limit: float) -> list[str]:
    """Warnings about the current column (A): mA instead of A, or saturation."""
    found = []
    peak = float(np.abs(run.current).max())
    if peak > 50 * current_limit:
        found.append(
            f"{run.source}: 'current' peaks at {peak:.4g}, 50x the current limit "
            f"{current_limit} A: is it in mA?"
        )
    saturated = float(np.mean(np.abs(run.current) >= 0.999 * current_limit))
    if saturated > 0.01:
        found.append(f"{run.source}: the current is at its limit in {saturated:.1%} of the samples")
    return found
