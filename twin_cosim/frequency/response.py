"""A frequency response: what was measured (or computed), at which lines, with what coherence.

The loops a drive measures and what each response is:

- ``plant``: the mechanics as the drive sees them, motor speed over the torque setpoint
  (rad/s per N.m, eq. (3)), measured open through the closed loops (indirect method); the
  zero-order hold of the drive's sample period is taken out, so that it compares with the
  continuous eq. (3), up to :data:`PLANT_BAND` of the Nyquist frequency (1 kHz at 62.5 us),
  below which what the hold aliases stays under 0.1 dB;
- ``speed``: the speed loop, open L_v (speed error -> motor speed) or closed T_v (speed
  setpoint -> motor speed), 1;
- ``position``: the position loop, open L_x (position error -> scale reading) or closed T_x
  (position setpoint -> scale reading), 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LOOPS = ("plant", "speed", "position")
PLANT_BAND = 1 / 8  # of the Nyquist frequency: the continuous plant response is given below
UNITS = {"plant": "rad/s per N.m", "speed": "1", "position": "1"}
DESCRIPTIONS = {
    ("plant", "open"): "motor speed over torque setpoint (eq. (3))",
    ("speed", "open"): "speed loop, open: speed error -> motor speed",
    ("speed", "closed"): "speed loop, closed: speed setpoint -> motor speed",
    ("position", "open"): "position loop, open: position error -> scale reading",
    ("position", "closed"): "position loop, closed: position setpoint -> scale reading",
}


def check_loop(loop: str, kind: str) -> None:
    """ValueError unless (loop, kind) is a response a drive measures."""
    if loop not in LOOPS:
        raise ValueError(f"loop {loop!r}: expected one of {list(LOOPS)}")
    if (loop, kind) not in DESCRIPTIONS:
        raise ValueError(
            f"--loop {loop} --{kind}: the plant is measured open (the mechanics, through the "
            "closed loops); --closed applies to the speed and position loops"
        )


@dataclass(frozen=True)
class FrequencyResponse:
    """Complex response values at increasing frequencies.

    Attributes
    ----------
    loop : str
        plant, speed or position (:data:`LOOPS`).
    kind : str
        open or closed.
    frequency_hz : numpy.ndarray
        Frequencies, Hz.
    response : numpy.ndarray
        Complex values, unit :data:`UNITS` of the loop.
    coherence : numpy.ndarray or None
        gamma^2 per frequency (None for a computed response).
    """

    loop: str
    kind: str
    frequency_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray | None = None

    def below(self, frequency_hz: float) -> FrequencyResponse:
        """The response at the lines up to ``frequency_hz`` (Hz)."""
        keep = self.frequency_hz <= frequency_hz
        return FrequencyResponse(
            self.loop,
            self.kind,
            self.frequency_hz[keep],
            self.response[keep],
            None if self.coherence is None else self.coherence[keep],
        )

    @property
    def magnitude_db(self) -> np.ndarray:
        """20 log10 |H|, dB (re 1 of the loop's unit)."""
        return 20 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """The phase, degrees in (-180, 180]."""
        return np.degrees(np.angle(self.response))

    @property
    def unit(self) -> str:
        """The unit of the response values."""
        return UNITS[self.loop]

    @property
    def description(self) -> str:
        """What the response is, in words."""
        return DESCRIPTIONS[(self.loop, self.kind)]
