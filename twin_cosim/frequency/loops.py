"""The P-PI cascade linearised at its sample rates: what the measured responses are compared with.

The plant (:class:`~twin_cosim.frequency.two_mass.TwoMass`) is discretised exactly with a
zero-order hold at the speed-loop period T (the controller holds the current over each period and
reads the motor speed at its start), its dead time as whole periods of delay. The speed
controller at T, from the speed error e to the current::

    C(z) = Kp_vel + Ki_vel z / (z - 1)        (I += Ki_vel e, then i = Kp_vel e + I)

followed by the current-setpoint filters F(z) (:mod:`twin_cosim.current_filters`). The speed
loop's open loop is L_v = C F P_w (from e to the motor speed), its closed loop T_v = L_v /
(1 + L_v). The position loop runs every R = position_period / T speed samples and holds its
speed command Kp_pos (x_ref - x) / travel over them: with the speed loop closed inside, the map
from that command to the scale reading x sampled every position period is exactly linear and
time-invariant at the position period (lifting: A^R, sum of A^j B), so L_x = Kp_pos / travel x
that map. The linearisation drops what is not linear: friction and its compensation, backlash,
the reversal pulse, the current limit, and the feedforwards (they do not act on the loop).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.frequency.two_mass import TwoMass


@dataclass(frozen=True)
class Discrete:
    """A discrete-time linear system x' = A x + B u, y = C x + D u.

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        State-space matrices.
    dt : float
        Sample period, s.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    dt: float

    def response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The frequency response at z = exp(j 2 pi f dt), shape (frequencies, outputs, inputs)."""
        z = np.exp(2j * np.pi * np.asarray(frequency_hz, dtype=np.float64) * self.dt)
        n = self.a.shape[0]
        if n == 0:
            return np.broadcast_to(self.d, (len(z), *self.d.shape)).astype(complex)
        solved = np.linalg.solve(z[:, None, None] * np.eye(n) - self.a, self.b)
        return self.c @ solved + self.d

    def siso(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The response of the first output to the first input, complex."""
        return self.response(frequency_hz)[:, 0, 0]


def series(first: Discrete, second: Discrete) -> Discrete:
    """``first`` then ``second`` (the outputs of ``first`` feed ``second``)."""
    n1, n2 = first.a.shape[0], second.a.shape[0]
    a = np.zeros((n1 + n2, n1 + n2))
    a[:n1, :n1] = first.a
    a[n1:, :n1] = second.b @ first.c
    a[n1:, n1:] = second.a
    b = np.vstack([first.b, second.b @ first.d])
    c = np.hstack([second.d @ first.c, second.c])
    return Discrete(a, b, c, second.d @ first.d, first.dt)


def closed(loop: Discrete) -> Discrete:
    """Unity negative feedback of the first output around a strictly proper ``loop``.

    Input: the setpoint r (e = r - y_0); outputs: those of ``loop``.
    """
    if np.any(loop.d[0] != 0.0):
        raise ValueError("closed: the loop must be strictly proper (no direct feedthrough)")
    a = loop.a - loop.b[:, :1] @ loop.c[:1]
    return Discrete(a, loop.b[:, :1], loop.c, np.zeros((loop.c.shape[0], 1)), loop.dt)


def lifted(system: Discrete, ratio: int) -> Discrete:
    """The system with its input held over ``ratio`` samples, sampled every ``ratio`` samples."""
    n = system.a.shape[0]
    power = np.eye(n)
    total = np.zeros((n, n))
    for _ in range(ratio):
        total = total + power
        power = power @ system.a
    return Discrete(power, total @ system.b, system.c, system.d, system.dt * ratio)


@functools.cache
def hold_discretised(plant: TwoMass, period: float, with_position: bool) -> Discrete:
    """The plant discretised with a zero-order hold at ``period`` (s), its dead time included
    (computed once per plant and period).

    Raises
    ------
    ValueError
        When the dead time is not a whole number of periods.
    """
    a, b, c = plant.state_space(with_position)
    n = a.shape[0]
    block = np.zeros((n + 1, n + 1))
    block[:n, :n], block[:n, n:] = a, b
    exact = expm(block * period)
    held = Discrete(exact[:n, :n], exact[:n, n:], c, np.zeros((c.shape[0], 1)), period)
    steps = plant.dead_time / period
    if abs(steps - round(steps)) > 1e-6:
        raise ValueError(
            f"dead time {plant.dead_time:g} s: the linearised loop needs a whole number of "
            f"speed-loop periods ({period:g} s)"
        )
    return series(delay(round(steps), period), held) if round(steps) else held


def delay(steps: int, period: float) -> Discrete:
    """A delay of ``steps`` samples (a shift register)."""
    a = np.eye(steps, k=-1)
    b = np.zeros((steps, 1))
    b[0, 0] = 1.0
    c = np.zeros((1, steps))
    c[0, -1] = 1.0
    return Discrete(a, b, c, np.zeros((1, 1)), period)


def speed_controller(tuned: TunedParameters, settings: ControllerSettings) -> Discrete:
    """The speed PI and the current-setpoint filters, from the speed error to the current.

    PI state: the integral before this sample, I_k = I_(k-1) + Ki e_k, i_k = Kp e_k + I_k.
    """
    period = settings.speed_period
    pi = Discrete(
        np.ones((1, 1)),
        np.array([[tuned.Ki_vel]]),
        np.ones((1, 1)),
        np.array([[tuned.Kp_vel + tuned.Ki_vel]]),
        period,
    )
    chain = pi
    for section in settings.filters:
        b0, b1, b2, a1, a2 = current_filters.coefficients(section, period)
        chain = series(
            chain,
            Discrete(  # direct form II transposed
                np.array([[-a1, 1.0], [-a2, 0.0]]),
                np.array([[b1 - a1 * b0], [b2 - a2 * b0]]),
                np.array([[1.0, 0.0]]),
                np.array([[b0]]),
                period,
            ),
        )
    return chain


@dataclass(frozen=True)
class LinearLoops:
    """The cascade of a scenario linearised: plant, controller, settings.

    Attributes
    ----------
    plant : TwoMass
        The plant's linear model.
    tuned : TunedParameters
        The controller's gains.
    settings : ControllerSettings
        Periods, the drive's torque constant and travel, the current filters.
    """

    plant: TwoMass
    tuned: TunedParameters
    settings: ControllerSettings

    @property
    def ratio(self) -> int:
        """Speed-loop samples per position-loop sample."""
        return self.settings.speed_steps_per_position_step

    def plant_response(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Motor speed over the drive's torque setpoint K_t,drive i (continuous), rad/s per N.m.

        Eq. (3) (with viscous friction), times the plant's torque per current (K_t, lag, dead
        time) over the torque constant the drive assumes.
        """
        return (
            self.plant.speed_per_torque(frequency_hz)
            * self.plant.torque_per_current(frequency_hz)
            / self.settings.torque_constant
        )

    def speed_open(self) -> Discrete:
        """L_v: speed error -> motor speed, at the speed-loop period."""
        plant = hold_discretised(self.plant, self.settings.speed_period, with_position=False)
        return series(speed_controller(self.tuned, self.settings), plant)

    def position_open(self) -> Discrete:
        """L_x: position error -> scale reading, at the position-loop period (lifted)."""
        plant = hold_discretised(self.plant, self.settings.speed_period, with_position=True)
        speed_loop = closed(series(speed_controller(self.tuned, self.settings), plant))
        inner = lifted(speed_loop, self.ratio)
        gain = self.tuned.Kp_pos / self.settings.travel_per_rad
        return Discrete(inner.a, inner.b * gain, inner.c[1:], inner.d[1:] * gain, inner.dt)

    def open_loop(self, loop: str) -> Discrete:
        """The open loop of ``speed`` or ``position``."""
        return self.speed_open() if loop == "speed" else self.position_open()

    def response(self, loop: str, kind: str, frequency_hz: np.ndarray) -> np.ndarray:
        """The linearised counterpart of a measured response, complex.

        ``loop``: plant, speed or position; ``kind``: open or closed.
        """
        if loop == "plant":
            return self.plant_response(frequency_hz)
        system = self.open_loop(loop) if kind == "open" else closed(self.open_loop(loop))
        return system.siso(frequency_hz)


def speed_loop_of_plant(
    tuned: TunedParameters,
    settings: ControllerSettings,
    frequency_hz: np.ndarray,
    plant_response: np.ndarray,
) -> np.ndarray:
    """The speed loop's open loop from a plant response, as a tuner computes it, complex.

    ``plant_response``: motor speed over the torque setpoint (rad/s per N.m, continuous, at
    ``frequency_hz``); the loop is C(z) F(z) K_t,drive P(j w) times the zero-order hold.
    """
    controller = speed_controller(tuned, settings).siso(frequency_hz)
    hold = hold_factor(frequency_hz, settings.speed_period)
    return controller * settings.torque_constant * plant_response * hold


def hold_factor(frequency_hz: np.ndarray, period: float) -> np.ndarray:
    """The zero-order hold's response exp(-j w T/2) sinc(f T): a held sample sequence against
    the continuous signal it stands for, complex."""
    f = np.asarray(frequency_hz, dtype=np.float64)
    return np.exp(-1j * math.pi * f * period) * np.sinc(f * period)
