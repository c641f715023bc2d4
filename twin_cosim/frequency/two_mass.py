"""The linear two-mass plant of the paper, eqs. (1)-(4), with viscous friction, lag and dead time.

Motor-referred, with twist d = q_M - q_L::

    J_M dw_M/dt = M_M - K d - B (w_M - w_L)
    J_L dw_L/dt = K d + B (w_M - w_L) - F_V w_L

With F_V = 0 the motor speed over the motor torque is eq. (3),

    H(s) = 1 / (J_M s) (s^2 + 2 D_1 w_01 s + w_01^2) / (s^2 + 2 D_2 w_02 s + w_02^2),

w_01 = sqrt(K / J_L) (the antiresonance), w_02 = w_01 sqrt(1 + J_L / J_M) (the resonance),
D_1 = B / (2 w_01 J_L), D_2 = D_1 sqrt(1 + J_L / J_M) (eqs. (1)-(2)), and the load over the motor
speed is eq. (4). The drive's current i becomes the motor torque M_M = K_t i_a through a
first-order current-loop lag (i_a) and a dead time; the scale reads x = travel q_L.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

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

    def state_space(self, with_position: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Continuous (A, B, C) from the current command (A, without the dead time).

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
        b_in = np.zeros((n, 1))
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
