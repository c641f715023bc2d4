"""Short scenario files for tests: moves out (and back) between dwells, as scenario YAML text."""

from __future__ import annotations

import textwrap


def scenario_text(
    name: str = "short",
    *,
    speed: float = 0.005,
    acceleration: float = 0.05,
    move: float = 0.3,
    stop: float = 0.1,
    dwell: float = 0.1,
    back: bool = True,
    repeat: int = 1,
    optimize: str = "",
) -> str:
    """Scenario text: ``repeat`` times (dwell, move out, move back, stop), then a dwell.

    Parameters
    ----------
    name
        Scenario name.
    speed
        Speed of the moves, m/s.
    acceleration
        Acceleration of every ramp, m/s^2.
    move
        Duration of each move (ramp and constant speed), s.
    stop
        Duration of the ramp to standstill, s.
    dwell
        Duration of each dwell, s.
    back
        Whether each pattern moves back at -``speed`` (a reversal while moving).
    repeat
        Number of patterns.
    optimize
        Body of the ``optimize`` section (YAML lines, unindented); none when empty.
    """

    def ramp(velocity: float, duration: float) -> str:
        return (
            f"    - ramp: {{velocity: {velocity}, acceleration: {acceleration}, "
            f"duration: {duration}}}\n"
        )

    pattern = f"    - dwell: {dwell}\n" + ramp(speed, move)
    pattern += (ramp(-speed, move) if back else "") + ramp(0.0, stop)
    text = f"name: {name}\nreference:\n  segments:\n" + pattern * repeat + f"    - dwell: {dwell}\n"
    return text + (f"optimize:\n{textwrap.indent(optimize.strip(), '  ')}\n" if optimize else "")
