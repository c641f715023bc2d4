"""Runs in the EMPS benchmark's .mat format: write one, and make a validation-like trajectory.

The format is that of the published files (Janot, Gautier, Brunot 2019): column vectors ``t``
(s), ``qg`` (reference, m), ``qm`` (measured motor position on the load side, m), ``vir`` (the
recorded drive command, V), scalars ``kp`` (1/s), ``kv`` (V/(m/s)) and ``gtau`` (N/V), and for a
cross-test validation run ``pulses_N``, one value per sample.

:func:`write_emps_mat` writes a record of the twin in that format (what ``twin synth --out
RUN.mat`` does, with the gains of :func:`emps_gains`); :func:`pulse_template` makes the
reference and pulse train of a validation-like run (bang-bang accelerations between seeded
random positions, with pulses added to the drive command), whose ``qm`` and ``vir`` are
placeholders until ``twin synth --follow`` fills them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.io import savemat

from twin_cosim.measured import read_measured
from twin_cosim.plant import Plant
from twin_cosim.reference import Dwell, Move, sample_segments
from twin_cosim.scenario import Scenario

SAMPLE_PERIOD = 1e-3  # s, the benchmark's rate


def write_emps_mat(
    path: Path,
    t: np.ndarray,
    reference: np.ndarray,
    position: np.ndarray,
    command: np.ndarray,
    gains: dict[str, float],
    pulses: np.ndarray | None = None,
) -> Path:
    """Write a run as an EMPS .mat file.

    Parameters
    ----------
    path : Path
        File to write.
    t, reference, position, command : numpy.ndarray
        Time (s), reference and measured position (m), recorded drive command (V).
    gains : dict
        ``kp`` (1/s), ``kv`` (V/(m/s)) and ``gtau`` (N/V).
    pulses : numpy.ndarray or None
        ``pulses_N`` per sample (a validation run), or None.
    """
    data = {
        "t": np.asarray(t, float)[:, None],
        "qg": np.asarray(reference, float)[:, None],
        "qm": np.asarray(position, float)[:, None],
        "vir": np.asarray(command, float)[:, None],
        **{k: np.array([[float(gains[k])]]) for k in ("kp", "kv", "gtau")},
    }
    if pulses is not None:
        data["pulses_N"] = np.asarray(pulses, float)[:, None]
    savemat(path, data)
    return path


def pulse_template(
    path: Path,
    seed: int,
    gains: dict[str, float],
    duration: float = 20.0,
    travel: tuple[float, float] = (0.01, 0.23),
    velocity: float = 0.1,
    acceleration: float = 0.8,
    pulse_height: float = 1.0,
    pulse_length: float = 0.15,
) -> Path:
    """A validation-like run: bang-bang moves between random positions, with a pulse train.

    Parameters
    ----------
    path : Path
        The .mat file to write.
    seed : int
        Seed of the positions, dwells and pulse times.
    gains : dict
        ``kp``, ``kv``, ``gtau`` of the controller.
    duration : float
        Least length of the run, s.
    travel : tuple of float
        Range of the move targets, m.
    velocity, acceleration : float
        Speed (m/s) and acceleration (m/s^2) limits of the moves.
    pulse_height : float
        Height of each pulse, in the unit of ``pulses_N`` (as the scenario's convention reads
        it), alternating in sign.
    pulse_length : float
        Length of each pulse, s.
    """
    rng = np.random.default_rng(seed)
    segments: list = [Dwell(0.5)]
    total, position = 0.5, travel[0]
    while total < duration:
        target = float(rng.uniform(*travel))
        distance = abs(target - position)
        total += distance / velocity + velocity / acceleration + 0.3
        segments += [Move(target, velocity, acceleration), Dwell(0.3)]
        position = target
    reference = sample_segments(segments, SAMPLE_PERIOD, travel[0])
    t = np.arange(len(reference)) * SAMPLE_PERIOD
    pulses = np.zeros_like(t)
    starts = np.sort(rng.uniform(1.0, t[-1] - 1.0, size=max(2, int(t[-1] / 2.0))))
    for k, start in enumerate(starts):
        pulses[(t >= start) & (t < start + pulse_length)] = pulse_height * (-1) ** k
    return write_emps_mat(path, t, reference, reference, np.zeros_like(t), gains, pulses)


def emps_gains(
    scenario: Scenario, follow: Path | str | None, fmu: Path | str | None
) -> dict[str, float]:
    """The scalars ``kp`` (1/s), ``kv`` (V/(m/s)) and ``gtau`` (N/V) of an EMPS-format run.

    Parameters
    ----------
    scenario
        The scenario the run followed.
    follow
        The measured run it followed (``twin synth --follow``); its gains when it has all three.
    fmu
        The plant (``--plant``); none: the scenario's. Its ``drive_gain`` start value is
        ``gtau`` (1 when it has none).

    Returns
    -------
    dict
        The followed run's gains, else the scenario's: ``kp`` its position gain, ``kv`` its
        speed gain per m/s of the load, ``gtau`` the plant's drive gain.
    """
    measured = read_measured(follow) if follow else None
    scalars = measured.scalars if measured else {}
    if all(k in scalars for k in ("kp", "kv", "gtau")):
        return {k: float(scalars[k]) for k in ("kp", "kv", "gtau")}
    with Plant(scenario.plant_fmu(fmu)) as plant:
        gtau = plant.start_values().get("drive_gain", 1.0)
    tuned, settings = scenario.tuned, scenario.settings
    return {
        "kp": tuned.Kp_pos,
        "kv": tuned.Kp_vel / settings.travel_per_rad,
        "gtau": gtau,
    }


def main(argv: list[str] | None = None) -> int:
    """``python -m twin_cosim.emps_runs --out T.mat``: write a validation-like pulse template."""
    import argparse

    parser = argparse.ArgumentParser(
        description="Write an EMPS-format template: bang-bang moves and a pulse train, for "
        "`twin synth SCENARIO --follow T.mat`",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--out", required=True, help="the .mat file to write")
    parser.add_argument("--seed", type=int, default=0, help="seed of moves and pulses")
    parser.add_argument("--duration", type=float, default=20.0, help="least length, s")
    parser.add_argument(
        "--pulse-height", type=float, default=3.0, help="pulse height, unit of pulses_N"
    )
    parser.add_argument("--kp", type=float, default=160.18, help="position gain, 1/s")
    parser.add_argument("--kv", type=float, default=243.45, help="speed gain, V/(m/s)")
    parser.add_argument("--gtau", type=float, default=35.15065188, help="drive gain, N/V")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.exists():
        parser.error(f"--out {out}: the file exists; choose another name")
    gains = {"kp": args.kp, "kv": args.kv, "gtau": args.gtau}
    pulse_template(out, args.seed, gains, args.duration, pulse_height=args.pulse_height)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
