"""The CNC's P-PI cascade controller with feedforward, reversal pulse and friction compensation.

Written as plain functions over float64 arrays so that the same code runs in Python (the readable
reference path) and compiled by numba (the fast path, see :mod:`twin_cosim.cosim`).

Control law (paper section II.B, eqs. (6)-(7)); all motor-side quantities refer to the motor shaft,
``travel`` is the carriage travel per motor radian (m/rad).

Position loop, every ``position_period`` (250 us), on the measured carriage position x [m]::

    w_cmd = (Kp_pos (x_ref - x) + ff_velocity v_ref) / travel                    [rad/s]
    i_ff  = ff_acceleration J a_ref / (travel K_t) + d F_comp / K_t              [A]

Direction relay d (the hysteresis f_H): d becomes +1 when the reference motor speed
v_ref / travel exceeds +f_H, -1 when it falls below -f_H, and holds otherwise. Each flip starts a
reversal pulse and turns the friction compensation around.

Speed loop, every ``speed_period`` (62.5 us), on the measured motor speed w [rad/s]::

    e   = w_cmd + d PP2 exp(-(t - t_flip) / PP3) - w                              [rad/s]
    I  += Ki_vel e                                (integral gain per speed-loop sample)
    i   = clip(F(Kp_vel e + I + i_ff), -i_max, i_max), integrator frozen while clipped [A]

F is the chain of current-setpoint filters (notch and low-pass sections, Tustin prewarped, see
:mod:`twin_cosim.current_filters`); without filters F is the identity and the current is
computed exactly as without the chain. The filters' states advance every sample, clipped or not.

Units of the six tuned parameters K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H]:
1/s, A/(rad/s), A/(rad/s) per speed-loop sample (Ki_vel / speed_period is the continuous integral
gain in A/rad), rad/s, s, rad/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from twin_cosim import current_filters
from twin_cosim.current_filters import CurrentFilter
from twin_cosim.plant_model import plant_model

TUNED_NAMES = ("Kp_pos", "Kp_vel", "Ki_vel", "PP2", "PP3", "f_H")

# The plant facts of the default settings: the default plant model's card at its start values.
_DEFAULT_FACTS = plant_model().drive_facts()

# Indices into the parameter vector built by ControllerConfig.vector().
KP_POS, KP_VEL, KI_VEL, PP2, PP3, F_H = range(6)
TRAVEL, FF_VELOCITY, FF_ACCELERATION, INERTIA, TORQUE_CONSTANT = range(6, 11)
FRICTION_TORQUE, CURRENT_LIMIT = range(11, 13)
FILTER_COUNT = 13  # number of current-setpoint filter sections, then their coefficients
FILTER_COEFFICIENTS = 14  # [b0, b1, b2, a1, a2] of each section from here on
PARAMETER_COUNT = 14  # without filter sections

# Indices into the controller state vector.
SPEED_CMD, CURRENT_FF, INTEGRAL, DIRECTION, FLIP_TIME = range(5)
FILTER_STATES = 5  # [z1, z2] of each filter section from here on
STATE_COUNT = 5  # without filter sections


@dataclass(frozen=True)
class TunedParameters:
    """The six parameters the paper tunes, eq. (7).

    Attributes
    ----------
    Kp_pos : float
        Position-loop proportional gain, 1/s (carriage speed command per position error).
    Kp_vel : float
        Speed-loop proportional gain, A/(rad/s) of motor speed error.
    Ki_vel : float
        Speed-loop integral gain per speed-loop sample, A/(rad/s): I += Ki_vel * error each sample.
    PP2 : float
        Reversal (backlash) pulse amplitude added to the speed command, rad/s.
    PP3 : float
        Reversal pulse time constant, s.
    f_H : float
        Hysteresis of the direction detection on the reference motor speed, rad/s.
    """

    Kp_pos: float
    Kp_vel: float
    Ki_vel: float
    PP2: float
    PP3: float
    f_H: float

    def __post_init__(self) -> None:
        for name in TUNED_NAMES:
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"controller parameter {name} must be finite, got {value}")
        for name in ("Kp_pos", "Kp_vel", "PP3"):
            if getattr(self, name) <= 0:
                raise ValueError(
                    f"controller parameter {name} must be > 0, got {getattr(self, name)}"
                )
        for name in ("Ki_vel", "PP2", "f_H"):
            if getattr(self, name) < 0:
                raise ValueError(
                    f"controller parameter {name} must be >= 0, got {getattr(self, name)}"
                )

    def as_array(self) -> np.ndarray:
        """[Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] as float64."""
        return np.array([getattr(self, n) for n in TUNED_NAMES], dtype=np.float64)

    @classmethod
    def from_array(cls, values: np.ndarray) -> TunedParameters:
        """Inverse of :meth:`as_array`."""
        return cls(*(float(v) for v in values))

    def as_dict(self) -> dict[str, float]:
        """The six parameters by name."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class ControllerSettings:
    """Fixed (not tuned) settings of the controller.

    The plant facts (travel_per_rad, inertia, torque_constant, friction_torque, speed_period)
    default to those of the default plant model (drive2mass) at its start values, as its card
    states them (:mod:`twin_cosim.plant_model`); a scenario takes them from its own plant model
    and parameters.

    Attributes
    ----------
    travel_per_rad : float
        Carriage travel per motor radian, m/rad (spindle constant / gear ratio).
    ff_velocity : float
        Velocity feedforward gain, 1 (1.0 = the full reference speed).
    ff_acceleration : float
        Acceleration feedforward gain, 1 (1.0 = the full J a_ref torque).
    inertia : float
        Total inertia used by the acceleration feedforward, kg.m2 (J_M + J_L).
    torque_constant : float
        Motor torque constant the drive assumes, N.m/A.
    friction_torque : float
        Friction compensation torque, N.m.
    current_limit : float
        Current limit, A.
    position_period : float
        Position-loop period, s.
    speed_period : float
        Speed-loop period, s; must divide position_period. The plant model's sample period (the
        FMU is stepped at it).
    filters : tuple
        Current-setpoint filter sections (:class:`~twin_cosim.current_filters.Notch`,
        :class:`~twin_cosim.current_filters.LowPass`) in the order the setpoint passes them;
        each frequency below the speed loop's Nyquist frequency. None by default.
    """

    travel_per_rad: float = _DEFAULT_FACTS["travel_per_rad"]
    ff_velocity: float = 1.0
    ff_acceleration: float = 1.0
    inertia: float = _DEFAULT_FACTS["inertia"]
    torque_constant: float = _DEFAULT_FACTS["torque_constant"]
    friction_torque: float = _DEFAULT_FACTS["friction_torque"]
    current_limit: float = 20.0
    position_period: float = 250e-6
    speed_period: float = _DEFAULT_FACTS["speed_period"]
    filters: tuple[CurrentFilter, ...] = ()

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name == "filters":
                continue
            value = getattr(self, f.name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(
                    f"controller setting {f.name} must be finite and >= 0, got {value}"
                )
        for name in (
            "travel_per_rad",
            "torque_constant",
            "current_limit",
            "position_period",
            "speed_period",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"controller setting {name} must be > 0")
        ratio = self.position_period / self.speed_period
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(
                f"controller settings: position_period {self.position_period} s must be a whole "
                f"multiple of speed_period {self.speed_period} s"
            )
        current_filters.check_below_nyquist(self.filters, self.speed_period)

    @property
    def speed_steps_per_position_step(self) -> int:
        """Speed-loop samples per position-loop sample."""
        return round(self.position_period / self.speed_period)


def parameter_vector(tuned: TunedParameters, settings: ControllerSettings) -> np.ndarray:
    """The flat float64 parameter vector read by :func:`position_loop` and :func:`speed_loop`.

    Its tail holds the filter sections: their number, then [b0, b1, b2, a1, a2] of each at the
    speed-loop period.
    """
    sections = len(settings.filters)
    p = np.empty(
        PARAMETER_COUNT + current_filters.COEFFICIENTS_PER_SECTION * sections, dtype=np.float64
    )
    p[:6] = tuned.as_array()
    p[TRAVEL] = settings.travel_per_rad
    p[FF_VELOCITY] = settings.ff_velocity
    p[FF_ACCELERATION] = settings.ff_acceleration
    p[INERTIA] = settings.inertia
    p[TORQUE_CONSTANT] = settings.torque_constant
    p[FRICTION_TORQUE] = settings.friction_torque
    p[CURRENT_LIMIT] = settings.current_limit
    p[FILTER_COUNT] = sections
    for j, section in enumerate(settings.filters):
        start = FILTER_COEFFICIENTS + current_filters.COEFFICIENTS_PER_SECTION * j
        p[start : start + current_filters.COEFFICIENTS_PER_SECTION] = current_filters.coefficients(
            section, settings.speed_period
        )
    return p


def initial_state(sections: int = 0) -> np.ndarray:
    """Controller state at rest: no command, empty integrator, no direction yet, filters at 0.

    ``sections`` is the number of current-setpoint filter sections.
    """
    s = np.zeros(STATE_COUNT + current_filters.STATES_PER_SECTION * sections, dtype=np.float64)
    s[FLIP_TIME] = -np.inf
    return s


def position_loop(
    p: np.ndarray, s: np.ndarray, t: float, x_ref: float, v_ref: float, a_ref: float, x: float
) -> None:
    """One position-loop sample at time ``t`` (s): update the speed command and feedforward.

    Parameters
    ----------
    p, s
        Parameter and state vectors (``s`` is updated in place).
    t
        Sample time, s.
    x_ref, v_ref, a_ref
        Reference position (m), speed (m/s) and acceleration (m/s^2) of the carriage.
    x
        Measured carriage position, m.
    """
    travel = p[TRAVEL]
    reference_speed = v_ref / travel
    direction = s[DIRECTION]
    if reference_speed > p[F_H] and direction != 1.0:
        s[DIRECTION] = 1.0
        s[FLIP_TIME] = t
    elif reference_speed < -p[F_H] and direction != -1.0:
        s[DIRECTION] = -1.0
        s[FLIP_TIME] = t
    s[SPEED_CMD] = (p[KP_POS] * (x_ref - x) + p[FF_VELOCITY] * v_ref) / travel
    s[CURRENT_FF] = (
        p[FF_ACCELERATION] * p[INERTIA] * a_ref / travel + s[DIRECTION] * p[FRICTION_TORQUE]
    ) / p[TORQUE_CONSTANT]


def speed_loop(p: np.ndarray, s: np.ndarray, t: float, w: float) -> float:
    """One speed-loop sample at time ``t`` (s) on the measured motor speed ``w`` (rad/s).

    Returns
    -------
    float
        Current command, A, within the current limit.
    """
    pulse = 0.0  # reversal pulse d PP2 exp(-(t - t_flip)/PP3), rad/s, eq. (6)
    if s[DIRECTION] != 0.0:
        pulse = s[DIRECTION] * p[PP2] * math.exp(-(t - s[FLIP_TIME]) / p[PP3])
    error = s[SPEED_CMD] + pulse - w
    integral = s[INTEGRAL] + p[KI_VEL] * error
    current = p[KP_VEL] * error + integral + s[CURRENT_FF]
    for j in range(int(p[FILTER_COUNT])):  # direct form II transposed, one section at a time
        c = FILTER_COEFFICIENTS + 5 * j
        z = FILTER_STATES + 2 * j
        filtered = p[c] * current + s[z]
        s[z] = p[c + 1] * current - p[c + 3] * filtered + s[z + 1]
        s[z + 1] = p[c + 2] * current - p[c + 4] * filtered
        current = filtered
    limit = p[CURRENT_LIMIT]
    if current > limit:
        return limit
    if current < -limit:
        return -limit
    s[INTEGRAL] = integral
    return current
