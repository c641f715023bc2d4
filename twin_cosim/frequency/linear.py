"""The linear model: the two-mass plant of the paper and the P-PI cascade linearised at its
sample rates, what the measured responses are compared with.

The plant, eqs. (1)-(4), with viscous friction, lag and dead time (:class:`TwoMass`);
motor-referred, with twist d = q_M - q_L::

    J_M dw_M/dt = M_M - K d - B (w_M - w_L)
    J_L dw_L/dt = K d + B (w_M - w_L) - F_V w_L

With F_V = 0 the motor speed over the motor torque is eq. (3),

    H(s) = 1 / (J_M s) (s^2 + 2 D_1 w_01 s + w_01^2) / (s^2 + 2 D_2 w_02 s + w_02^2),

w_01 = sqrt(K / J_L) (the antiresonance), w_02 = w_01 sqrt(1 + J_L / J_M) (the resonance),
D_1 = B / (2 w_01 J_L), D_2 = D_1 sqrt(1 + J_L / J_M) (eqs. (1)-(2)), and the load over the motor
speed is eq. (4). The drive's current i becomes the motor torque M_M = K_t i_a through a
first-order current-loop lag (i_a) and a dead time; the scale reads x = travel q_L.

The cascade (:class:`LinearLoops`): the plant is discretised exactly with a zero-order hold at
the speed-loop period T (the controller holds the current over each period and reads the motor
speed at its start), its dead time as whole periods of delay. The speed controller at T, from
the speed error e to the current::

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

import dataclasses
import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings, TunedParameters
from twin_cosim.plant_model import plant_model


@dataclass(frozen=True)
class TwoMass:
    """The linear two-mass plant, motor-referred.

    Attributes
    ----------
    motor_inertia : float
        J_M, kg.m2.
    load_inertia : float
        J_L, kg.m2.
    stiffness : float
        Coupling stiffness K, N.m/rad.
    damping : float
        Coupling damping B, N.m.s/rad.
    viscous_friction : float
        F_V on the load, N.m.s/rad.
    torque_constant : float
        K_t, N.m/A.
    travel_per_rad : float
        Carriage travel at the scale per load radian, m/rad.
    current_lag : float
        Time constant of the current loop, s (0: none).
    dead_time : float
        Dead time of the current, s (0: none).
    """

    motor_inertia: float
    load_inertia: float
    stiffness: float
    damping: float
    viscous_friction: float = 0.0
    torque_constant: float = 1.0
    travel_per_rad: float = 1.0
    current_lag: float = 0.0
    dead_time: float = 0.0

    @classmethod
    def of_plant(cls, model: str, parameters: Mapping[str, float] | None = None) -> TwoMass:
        """The linear plant of a plant model at these parameter values (its card's formulas)."""
        return cls(**plant_model(model).linear_plant(parameters))

    @classmethod
    def from_paper(
        cls,
        motor_inertia: float,
        load_inertia: float,
        antiresonance_hz: float,
        damping_ratio: float,
        **others: float,
    ) -> TwoMass:
        """From Table 1's quantities: J_M, J_L (kg.m2), f_1 (Hz) and D_1 (1), eqs. (1)-(2).

        ``others`` are the remaining attributes (viscous friction, torque constant, ...).
        """
        w01 = 2.0 * math.pi * antiresonance_hz
        return cls(
            motor_inertia,
            load_inertia,
            load_inertia * w01**2,
            2.0 * damping_ratio * w01 * load_inertia,
            **others,
        )

    def with_values(self, **changes: float) -> TwoMass:
        """A copy with some attributes changed."""
        return dataclasses.replace(self, **changes)

    @property
    def antiresonance_hz(self) -> float:
        """f_1 = w_01 / (2 pi), w_01 = sqrt(K / J_L), Hz."""
        return math.sqrt(self.stiffness / self.load_inertia) / (2.0 * math.pi)

    @property
    def resonance_hz(self) -> float:
        """w_02 / (2 pi) = f_1 sqrt(1 + J_L / J_M), Hz."""
        return self.antiresonance_hz * math.sqrt(1.0 + self.load_inertia / self.motor_inertia)

    @property
    def damping_ratio(self) -> float:
        """D_1 = B / (2 w_01 J_L), 1."""
        return self.damping / (2.0 * 2.0 * math.pi * self.antiresonance_hz * self.load_inertia)

    def speed_per_torque(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Motor speed over motor torque (eq. (3) with F_V), rad/s per N.m, complex."""
        s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
        coupling = self.damping + self.stiffness / s
        load = coupling / (self.load_inertia * s + self.viscous_friction + coupling)
        return 1.0 / (self.motor_inertia * s + coupling * (1.0 - load))

    def load_per_motor(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Load speed over motor speed (eq. (4) with F_V), 1, complex."""
        s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
        return (self.damping * s + self.stiffness) / (
            self.load_inertia * s**2 + (self.damping + self.viscous_friction) * s + self.stiffness
        )

    def torque_per_current(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Motor torque over current command: K_t, the lag and the dead time, N.m/A, complex."""
        s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
        return self.torque_constant * np.exp(-s * self.dead_time) / (1.0 + s * self.current_lag)

    def state_space(
        self, with_position: bool, with_disturbance: bool = False
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous (A, B, C) from the current command (A, without the dead time), and from the
        disturbance torque M_D at the load (N.m, motor-referred, opposing positive motion: the
        plant contract's ``disturbance_torque``) ``with_disturbance``.

        States: twist d [rad], w_M [rad/s], w_L [rad/s], then q_L [rad] ``with_position``, then
        the current i_a [A] when there is a lag. Outputs: w_M [rad/s], then x [m]
        ``with_position``.
        """
        j_m, j_l = self.motor_inertia, self.load_inertia
        k, b, f_v = self.stiffness, self.damping, self.viscous_friction
        rows = [
            [0.0, 1.0, -1.0],
            [-k / j_m, -b / j_m, b / j_m],
            [k / j_l, b / j_l, -(b + f_v) / j_l],
        ]
        n = 3 + with_position + (self.current_lag > 0)
        a = np.zeros((n, n))
        a[:3, :3] = rows
        b_in = np.zeros((n, 1 + with_disturbance))
        if with_disturbance:
            b_in[2, 1] = -1.0 / j_l
        c = np.zeros((1 + with_position, n))
        c[0, 1] = 1.0
        if with_position:
            a[3, 2] = 1.0
            c[1, 3] = self.travel_per_rad
        if self.current_lag > 0:
            a[1, n - 1] = self.torque_constant / j_m
            a[n - 1, n - 1] = -1.0 / self.current_lag
            b_in[n - 1, 0] = 1.0 / self.current_lag
        else:
            b_in[1, 0] = self.torque_constant / j_m
        return a, b_in, c


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
    """Unity negative feedback of the first output around the first input of ``loop`` (its
    first output strictly proper: no direct feedthrough).

    Inputs: the setpoint r (the first input becomes e = r - y_0), then the loop's other inputs
    (disturbances) as they are; outputs: those of ``loop``.
    """
    if np.any(loop.d[0] != 0.0):
        raise ValueError("closed: the loop must be strictly proper (no direct feedthrough)")
    feedback = loop.b[:, :1] @ loop.c[:1]
    c = loop.c - loop.d[:, :1] @ loop.c[:1]
    return Discrete(loop.a - feedback, loop.b, c, loop.d, loop.dt)


def with_passthrough(system: Discrete, count: int) -> Discrete:
    """``system`` with ``count`` more inputs passed unchanged to ``count`` more outputs (a
    disturbance carried past a controller to the plant's input)."""
    n, inputs, outputs = system.a.shape[0], system.b.shape[1], system.c.shape[0]
    b = np.hstack([system.b, np.zeros((n, count))])
    c = np.vstack([system.c, np.zeros((count, n))])
    d = np.zeros((outputs + count, inputs + count))
    d[:outputs, :inputs] = system.d
    d[outputs:, inputs:] = np.eye(count)
    return Discrete(system.a, b, c, d, system.dt)


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
def hold_discretised(
    plant: TwoMass, period: float, with_position: bool, with_disturbance: bool = False
) -> Discrete:
    """The plant discretised with a zero-order hold at ``period`` (s), its dead time included
    (on the current; computed once per plant and period). Inputs: the current, then the
    disturbance torque ``with_disturbance`` (both held over each period).

    Raises
    ------
    ValueError
        When the dead time is not a whole number of periods.
    """
    a, b, c = plant.state_space(with_position, with_disturbance)
    n, inputs = a.shape[0], b.shape[1]
    block = np.zeros((n + inputs, n + inputs))
    block[:n, :n], block[:n, n:] = a, b
    exact = expm(block * period)
    held = Discrete(exact[:n, :n], exact[:n, n:], c, np.zeros((c.shape[0], inputs)), period)
    steps = plant.dead_time / period
    if abs(steps - round(steps)) > 1e-6:
        raise ValueError(
            f"dead time {plant.dead_time:g} s: the linearised loop needs a whole number of "
            f"speed-loop periods ({period:g} s)"
        )
    if not round(steps):
        return held
    return series(with_passthrough(delay(round(steps), period), inputs - 1), held)


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

    def position_open(self, with_disturbance: bool = False) -> Discrete:
        """L_x: position error -> scale reading, at the position-loop period (lifted).

        ``with_disturbance``: a second input, the disturbance torque at the load (N.m, held over
        each position period, as the measurement injects it).
        """
        period = self.settings.speed_period
        plant = hold_discretised(self.plant, period, True, with_disturbance)
        controller = with_passthrough(
            speed_controller(self.tuned, self.settings), int(with_disturbance)
        )
        inner = lifted(closed(series(controller, plant)), self.ratio)
        gain = np.ones((1, inner.b.shape[1]))
        gain[0, 0] = self.tuned.Kp_pos / self.settings.travel_per_rad
        return Discrete(inner.a, inner.b * gain, inner.c[1:], inner.d[1:] * gain, inner.dt)

    def open_loop(self, loop: str) -> Discrete:
        """The open loop of ``speed`` or ``position``."""
        return self.speed_open() if loop == "speed" else self.position_open()

    def compliance(self, frequency_hz: np.ndarray) -> np.ndarray:
        """The closed cascade's scale reading per disturbance torque at the load, m/N.m,
        complex (negative at low frequency: the torque opposes positive motion)."""
        cascade = closed(self.position_open(with_disturbance=True))
        return cascade.response(frequency_hz)[:, 0, 1]

    def dynamic_stiffness(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Force at the carriage per position deviation, N/um, complex: the disturbance torque
        over the drive's travel per motor radian, against the reading it causes, with the sign
        that makes it positive where the axis yields to the force."""
        force_per_torque = 1.0 / self.settings.travel_per_rad  # N per N.m
        return -force_per_torque / self.compliance(frequency_hz) * 1e-6

    def response(self, loop: str, kind: str, frequency_hz: np.ndarray) -> np.ndarray:
        """The linearised counterpart of a measured response, complex.

        ``loop``: plant, speed, position or disturbance; ``kind``: open, closed (T = L / (1 + L))
        or sensitivity (S = 1 / (1 + L)); a disturbance response is the dynamic stiffness.
        """
        if loop == "plant":
            return self.plant_response(frequency_hz)
        if loop == "disturbance":
            return self.dynamic_stiffness(frequency_hz)
        open_loop = self.open_loop(loop).siso(frequency_hz)
        if kind == "open":
            return open_loop
        if kind == "sensitivity":
            return 1.0 / (1.0 + open_loop)
        return closed(self.open_loop(loop)).siso(frequency_hz)


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
