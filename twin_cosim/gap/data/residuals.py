"""Residuals of measured runs against the twin's replays, and the figures computed from them.

A residual is measured minus simulated: r_x = x_meas - x_sim (m) on the position the scale
reads, r_i = i_meas - i_sim (A, or the drive command's unit) on the recorded command. Each run is
compared with the replay of the scenario it follows (its own reference for a held-out run of a
scenario whose reference comes from a measured file, see
:func:`twin_cosim.scenario.for_measured_run`); the replay is interpolated at the run's samples.

An open-loop run (its plant driven by its own signal, :attr:`MeasuredRun.drive`) has no command
to compare: its second residual is the motor speed's, w_meas - w_sim (rad/s), in the place of the
current's (:attr:`MeasuredRun.compared`), and its regimes are those of an open-loop run
(:func:`twin_cosim.gap.data.regimes.classify_open_loop`). Its position residual counts from the
start of each level of its drive (:func:`anchored`): each step of the drive is an experiment
from the measured state, and a speed error in one level neither carries into the next level's
position gap nor cancels against it (a twin too fast in one level and too slow in the next would
otherwise end near the measured position).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from twin_cosim.gap.data import regimes as regime_model
from twin_cosim.gap.spectra import dominant_peak, mean_amplitude_spectrum
from twin_cosim.measured import MeasuredRun
from twin_cosim.metrics import UM_PER_M, indices
from twin_cosim.reference import ReferenceGrid
from twin_cosim.run_record import RunRecord

FIELDS = ("t", "position", "current", "regimes", "motor_angle", "x", "direction")


@dataclass(frozen=True)
class Residuals:
    """Residuals of a set of runs, concatenated over the runs.

    Attributes
    ----------
    t : numpy.ndarray
        Sample times, s.
    position : numpy.ndarray
        Position residual, m.
    current : numpy.ndarray
        Current (drive command) residual, A (or V); the motor speed residual (rad/s) of an
        open-loop run.
    regimes : numpy.ndarray
        Regime codes of :data:`twin_cosim.gap.data.regimes.REGIMES`.
    motor_angle : numpy.ndarray
        Motor angle of the replay, rad.
    x : numpy.ndarray
        Measured carriage position, m.
    direction : numpy.ndarray
        Sign of the reference speed (+1, -1; 0 at standstill).
    """

    t: np.ndarray
    position: np.ndarray
    current: np.ndarray
    regimes: np.ndarray
    motor_angle: np.ndarray
    x: np.ndarray
    direction: np.ndarray

    def normalised_energy(self, sigma_x: float, sigma_i: float) -> np.ndarray:
        """Per sample 0.5 ((r_x / sigma_x)^2 + (r_i / sigma_i)^2): 1 on average for pure noise."""
        return 0.5 * ((self.position / sigma_x) ** 2 + (self.current / sigma_i) ** 2)

    def normalised_rms(self, sigma_x: float, sigma_i: float) -> float:
        """sqrt(mean of the normalised energy): 1 when the residual is noise at the floors."""
        return math.sqrt(float(np.mean(self.normalised_energy(sigma_x, sigma_i))))

    def position_rms_um(self) -> float:
        """RMS of the position residual, um."""
        return rms(self.position) * UM_PER_M

    def current_rms(self) -> float:
        """RMS of the current residual, A."""
        return rms(self.current)

    def minus(self, position: np.ndarray, current: np.ndarray) -> Residuals:
        """The same samples with other residual values."""
        return Residuals(
            self.t, position, current, self.regimes, self.motor_angle, self.x, self.direction
        )


def rms(values: np.ndarray) -> float:
    """Root mean square of an array (its unit)."""
    return float(np.sqrt(np.mean(np.square(values)))) if len(values) else 0.0


def joined(parts: list[Residuals]) -> Residuals:
    """Several residual sets as one, samples one after the other."""
    return Residuals(*(np.concatenate([getattr(p, f) for p in parts]) for f in FIELDS))


def anchored(residual: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """A residual counted from each of ``starts`` (indices) on: its value at the start of each
    stretch subtracted over the stretch (the samples before the first start as they are)."""
    stretch = np.searchsorted(starts, np.arange(len(residual)), side="right") - 1
    offsets = np.where(stretch >= 0, residual[starts[np.maximum(stretch, 0)]], 0.0)
    return residual - offsets


def sim_at(record: RunRecord, column: str, t: np.ndarray) -> np.ndarray:
    """A replay's column interpolated at the times ``t`` (s)."""
    return np.interp(t, record["t"], record[column])


def run_residuals(run: MeasuredRun, record: RunRecord, grid: ReferenceGrid) -> Residuals:
    """Residuals of one run against the replay ``record`` of the scenario it follows."""
    v_ref = np.interp(run.t, grid.time, grid.velocity)
    a_ref = np.interp(run.t, grid.time, grid.acceleration)
    compared = run.compared
    position = run.x - sim_at(record, "x", run.t)
    if run.drive is None:
        regimes = regime_model.classify_regimes(run.t, v_ref, a_ref)
    else:
        commanded = run.experiment_input
        regimes = regime_model.classify_open_loop(run.t, run.record["motor_speed"], commanded)
        position = anchored(position, regime_model.drive_steps(commanded))
    return Residuals(
        run.t,
        position,
        run.record[compared] - sim_at(record, compared, run.t),
        regimes,
        sim_at(record, "motor_angle", run.t),
        run.x,
        np.where(np.abs(v_ref) > regime_model.RegimeSettings().v_still, np.sign(v_ref), 0.0),
    )


def residuals_of(
    runs: list[MeasuredRun], records: list[RunRecord], grids: list[ReferenceGrid]
) -> Residuals:
    """Residuals of runs, each against its own replay and reference grid."""
    return joined(
        [run_residuals(r, rec, g) for r, rec, g in zip(runs, records, grids, strict=True)]
    )


def run_metrics(t: np.ndarray, error: np.ndarray, current: np.ndarray) -> dict[str, float]:
    """E_pk (um), ITAE (um.s^2) and IAU (A.s) of one window, by :func:`indices`."""
    metrics = indices(t, error, current)
    return {"E_pk_um": metrics.E_pk_um, "ITAE": metrics.ITAE, "IAU": metrics.IAU}


def validation_figures(res: Residuals) -> dict[str, float]:
    """The paper's validation figures of the position gap: max, mean absolute, RMS (um)."""
    gap = np.abs(res.position) * UM_PER_M
    return {
        "max_um": float(gap.max()),
        "mean_abs_um": float(gap.mean()),
        "rms_um": float(np.sqrt(np.mean(gap**2))),
    }


def _derivatives(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration by central differences of a zero-phase low-passed position.

    The EMPS benchmark's band-pass process: a Butterworth filter (4th order) run forwards and
    backwards, cut at 1/10 of the sampling rate, then central differences.
    """
    from scipy.signal import butter, filtfilt

    dt = float(np.median(np.diff(t)))
    b, a = butter(4, 0.2)  # cut-off at 0.2 x Nyquist = fs / 10
    smooth = filtfilt(b, a, x) if len(x) > 15 else x
    velocity = np.gradient(smooth, dt)
    return velocity, np.gradient(velocity, dt)


PULSE_WINDOW = 0.2  # s after each edge of a disturbance signal


def pulse_response(
    run: MeasuredRun, record: RunRecord, signal: np.ndarray, grid: ReferenceGrid
) -> dict[str, float] | None:
    """How the acceleration residual concentrates after the edges of a disturbance signal.

    The edges are the samples where the signal (per position sample of ``grid``) jumps by at
    least half its largest jump. Returns the share of time and of acceleration-residual energy
    in the :data:`PULSE_WINDOW` after the edges, their ratio (``enrichment``), and the frequency
    (Hz) of the largest peak of the residual's spectrum inside those windows (``ringing_hz``,
    the frequency a flexibility excited by the pulses would ring at); None without edges.
    """
    jumps = np.abs(np.diff(signal))
    if len(jumps) == 0 or jumps.max() <= 0:
        return None
    edges = grid.time[1:][jumps >= 0.5 * jumps.max()]
    inside = np.zeros(len(run.t), dtype=bool)
    for edge in edges:
        inside |= (run.t >= edge) & (run.t < edge + PULSE_WINDOW)
    _, a = _derivatives(run.t, run.x)
    _, a_sim = _derivatives(run.t, sim_at(record, "x", run.t))
    residual = a - a_sim
    energy = residual**2
    total = float(energy.sum())
    time_share = float(inside.mean())
    energy_share = float(energy[inside].sum()) / total if total > 0 else 0.0
    dt = float(np.median(np.diff(run.t)))
    pieces = [residual[(run.t >= e) & (run.t < e + PULSE_WINDOW)] for e in edges]
    pieces = [p - p.mean() for p in pieces if len(p) > 8]
    ringing = None
    if pieces:
        frequency, amplitude = mean_amplitude_spectrum(pieces, dt)
        peak = dominant_peak(frequency[1:], amplitude[1:], min_ratio=0.0)
        ringing = float(peak.location) if peak else None
    return {
        "edges": len(edges),
        "time_share": time_share,
        "energy_share": energy_share,
        "enrichment": energy_share / time_share if time_share > 0 else 0.0,
        "ringing_hz": ringing,
    }


def relative_errors(run: MeasuredRun, record: RunRecord) -> dict[str, float]:
    """The benchmark's figures of merit 100 ||y - y_sim|| / ||y|| (%) of a run.

    Keys ``position`` (measured position), ``velocity`` and ``acceleration`` (both from the
    position by :func:`_derivatives`, the same for measured and simulated) and ``force`` (the
    recorded drive command, proportional to the force). An open-loop run has no ``force``: its
    command is the measured drive signal itself, the same in the twin.
    """
    x_sim = sim_at(record, "x", run.t)
    v, a = _derivatives(run.t, run.x)
    v_sim, a_sim = _derivatives(run.t, x_sim)

    def relative(measured: np.ndarray, simulated: np.ndarray) -> float:
        norm = float(np.linalg.norm(measured))
        return 100.0 * float(np.linalg.norm(measured - simulated)) / norm if norm else 0.0

    errors = {
        "position": relative(run.x, x_sim),
        "velocity": relative(v, v_sim),
        "acceleration": relative(a, a_sim),
    }
    if run.drive is None:
        errors["force"] = relative(run.current, sim_at(record, "current", run.t))
    return errors
