"""Regime labels of a hand-built reference and residual energy shares per regime."""

from __future__ import annotations

import numpy as np
import pytest

from twin_cosim.gap.data.regimes import (
    REGIMES,
    RegimeSettings,
    classify_open_loop,
    classify_regimes,
    drive_steps,
    energy_shares,
    segments,
    strokes,
)

DT = 1e-3  # s

# (time s, carriage speed m/s) knots of a piecewise-linear speed profile; acceleration 0.5 m/s^2
KNOTS = [
    (0.0, 0.0),
    (0.5, 0.0),  # dwell
    (0.7, 0.1),  # accelerate (first motion: breakaway)
    (1.5, 0.1),  # cruise
    (1.7, 0.0),  # decelerate
    (2.2, 0.0),  # dwell
    (2.4, -0.1),  # leave the dwell backwards: reversal
    (3.0, -0.1),  # cruise
    (3.4, 0.1),  # through zero at 3.2 s: reversal
    (4.0, 0.1),  # cruise
    (4.2, 0.0),  # decelerate
    (4.7, 0.0),  # dwell
    (4.9, 0.1),  # leave forwards again: breakaway
    (5.3, 0.1),  # cruise
]


def profile() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(round(KNOTS[-1][0] / DT) + 1) * DT
    knot_t, knot_v = np.array(KNOTS).T
    v = np.interp(t, knot_t, knot_v)
    return t, v, np.gradient(v, DT)


EXPECTED = {
    0.2: "standstill",
    0.52: "breakaway",
    0.6: "acceleration",
    1.0: "constant_velocity",
    1.6: "acceleration",
    1.9: "standstill",
    2.17: "reversal",
    2.24: "reversal",
    2.3: "acceleration",
    2.7: "constant_velocity",
    3.1: "acceleration",
    3.17: "reversal",
    3.23: "reversal",
    3.7: "constant_velocity",
    4.5: "standstill",
    4.68: "standstill",
    4.72: "breakaway",
    4.8: "acceleration",
    5.1: "constant_velocity",
}


@pytest.mark.parametrize(("instant", "regime"), EXPECTED.items())
def test_labels_at_chosen_instants(instant, regime):
    t, v, a = profile()
    labels = classify_regimes(t, v, a)
    assert REGIMES[labels[round(instant / DT)]] == regime


def test_window_setting_and_record_starting_in_motion():
    t, v, a = profile()
    wide = classify_regimes(t, v, a, RegimeSettings(window=0.1))
    assert REGIMES[wide[round(2.12 / DT)]] == "reversal"
    assert REGIMES[wide[round(4.78 / DT)]] == "breakaway"
    start = round(1.0 / DT)  # cut the record in the first cruise
    labels = classify_regimes(t[start:], v[start:], a[start:])
    assert REGIMES[labels[0]] == "constant_velocity"  # no breakaway at the record's start
    assert REGIMES[labels[round(2.24 / DT) - start]] == "reversal"


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="one length"):
        classify_regimes(np.arange(3.0), np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match="increase"):
        classify_regimes(np.zeros(3), np.zeros(3), np.zeros(3))


def test_energy_concentrated_in_reversals():
    t, v, a = profile()
    labels = classify_regimes(t, v, a)
    residual = np.where(labels == REGIMES.index("reversal"), 2e-6, 0.0)
    shares = energy_shares(residual, labels)
    assert set(shares) == set(REGIMES)
    assert sum(s["energy_share"] for s in shares.values()) == pytest.approx(1.0)
    assert sum(s["time_share"] for s in shares.values()) == pytest.approx(1.0)
    reversal = shares["reversal"]
    assert reversal["time_share"] == pytest.approx(np.mean(residual != 0.0))
    assert reversal["energy_share"] == pytest.approx(1.0)
    assert reversal["enrichment"] == pytest.approx(1.0 / reversal["time_share"])
    assert shares["constant_velocity"]["enrichment"] == 0.0


def test_enrichment_of_a_mixed_residual():
    labels = np.array([0, 0, 0, 3, 3, 3, 3, 3, 3, 3])
    residual = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5])
    shares = energy_shares(residual, labels)
    energy = 3.0 + 7 * 0.25
    assert shares["standstill"]["energy_share"] == pytest.approx(3.0 / energy)
    assert shares["standstill"]["enrichment"] == pytest.approx(3.0 / energy / 0.3)
    assert shares["constant_velocity"]["enrichment"] == pytest.approx(1.75 / energy / 0.7)


def test_zero_residual_and_absent_regimes():
    labels = np.zeros(50, dtype=int)
    with np.errstate(all="raise"):
        shares = energy_shares(np.zeros(50), labels)
    assert shares["standstill"] == {"time_share": 1.0, "energy_share": 0.0, "enrichment": 0.0}
    for name in REGIMES[1:]:
        assert shares[name] == {"time_share": 0.0, "energy_share": 0.0, "enrichment": 0.0}


def test_segments_of_one_regime():
    labels = np.array([3, 0, 0, 3, 3, 3, 0, 3])
    assert segments(labels, 3) == [(0, 1), (3, 6), (7, 8)]
    assert segments(labels, 0) == [(1, 3), (6, 7)]
    assert segments(labels, 4) == []


def test_sign_change_between_two_moving_samples_is_a_reversal():
    t = 0.37e-3 + np.arange(2000) * DT  # no sample on the crossings; the first after 0.5 s: 500
    v = 0.01 * np.sin(2 * np.pi * t)
    labels = classify_regimes(t, v, 0.02 * np.pi * np.cos(2 * np.pi * t))
    assert not np.any(labels == REGIMES.index("standstill"))
    assert segments(labels, REGIMES.index("reversal")) == [(450, 551), (950, 1051), (1450, 1551)]
    assert segments(labels, REGIMES.index("breakaway")) == []


def test_strokes_leave_out_the_grid_references_undershoot():
    """The 4 ms reference interpolated to the loop grid swings just beyond v_still the other way
    where a move starts or ends (a fraction of a micrometre): no stroke, so a move out, a stop,
    a dwell and the same move again are two strokes of one direction."""
    from twin_cosim.reference import interpolate

    t = np.arange(0, 1.2, 0.004)  # s
    knots = ([0.1, 0.2, 0.4, 0.5, 0.6, 0.7, 0.9, 1.0], [0, 0.005, 0.005, 0, 0, 0.005, 0.005, 0])
    grid = interpolate(np.cumsum(np.interp(t, *knots)) * 0.004, 0.004, 250e-6)
    still = RegimeSettings().v_still
    direction = np.where(np.abs(grid.velocity) > still, np.sign(grid.velocity), 0)
    assert np.any(direction < 0)  # the undershoot is there
    found = strokes(direction, grid.position)
    assert [sign for _, _, sign in found] == [1, 1]
    for a, b, _ in found:
        assert np.ptp(grid.position[a:b]) > 1e-3


def test_an_open_loop_run_is_run_up_steady_speed_and_after_the_step():
    """A rotor from rest under a torque stepped at 10 s: run-up (breakaway) until its speed
    settles within 5 % of the change, steady speed, the response after the step
    (acceleration), steady again; at rest before the torque acts: standstill."""
    t = np.arange(20000) * DT
    drive = np.where(t < 10.0, 0.05, 0.06)
    drive[:50] = 0.0  # no torque for 50 ms
    tau = 1.7  # s, J / B
    w1, w2 = 140.0, 210.0  # rad/s
    on = np.clip(t - 0.05, 0.0, None)
    speed = np.where(
        t < 10.0, w1 * (1 - np.exp(-on / tau)), w2 + (w1 - w2) * np.exp(-(t - 10.0) / tau)
    )
    labels = classify_open_loop(t, speed, drive)
    assert list(drive_steps(drive)) == [0, 50, 10000]
    assert set(labels[:20]) == {REGIMES.index("standstill")}  # (the running mean: 50 ms)
    settled = 0.05 + tau * np.log(1 / 0.05)  # 5 % of the change left: 3 time constants
    run_up = labels[(t > 0.2) & (t < settled - 0.2)]
    assert set(run_up) == {REGIMES.index("breakaway")}
    assert set(labels[(t > settled + 0.2) & (t < 10.0)]) == {REGIMES.index("constant_velocity")}
    after = labels[(t > 10.0) & (t < 10.0 + 3 * tau - 0.2)]
    assert set(after) == {REGIMES.index("acceleration")}
    assert set(labels[t > 10.0 + 3 * tau + 0.2]) == {REGIMES.index("constant_velocity")}


def test_starts_from_a_dwell_on_the_loop_grid_are_breakaways():
    """The undershoot before a start from a dwell (the spline through 4 ms samples swings just
    beyond v_still the other way) is no motion: a move, a dwell and the same move again start
    with two breakaways, and nothing there is a reversal."""
    from twin_cosim.reference import interpolate

    t = np.arange(0, 1.2, 0.004)  # s
    knots = ([0.1, 0.2, 0.4, 0.5, 0.6, 0.7, 0.9, 1.0], [0, 0.005, 0.005, 0, 0, 0.005, 0.005, 0])
    grid = interpolate(np.cumsum(np.interp(t, *knots)) * 0.004, 0.004, 250e-6)
    labels = classify_regimes(grid.time, grid.velocity, grid.acceleration)
    breakaways = segments(labels, REGIMES.index("breakaway"))
    assert len(breakaways) == 2
    for (first, _), start in zip(breakaways, (0.1, 0.6), strict=True):
        assert grid.time[first] == pytest.approx(start, abs=0.01)
    assert segments(labels, REGIMES.index("reversal")) == []


def test_the_shipped_excitation_starts_from_standstill_four_times():
    """scenarios/diagnosis.yaml leaves a dwell four times (once backwards: a reversal) and turns
    twice while moving: three breakaways and three reversals."""
    from twin_cosim.scenario import resolve_scenario

    grid = resolve_scenario("diagnosis").reference
    labels = classify_regimes(grid.time, grid.velocity, grid.acceleration)
    assert len(segments(labels, REGIMES.index("breakaway"))) == 3
    assert len(segments(labels, REGIMES.index("reversal"))) == 3
    assert energy_shares(np.ones(len(labels)), labels)["breakaway"]["time_share"] > 0.01
