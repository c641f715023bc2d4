"""What a servo engineer measures on an axis in the time domain, measured on the twin as a drive
measures it (docs/servo.md):

- :mod:`~twin_cosim.servo.motion`: the test motions on the master: a step of the position
  setpoint at standstill, and runs through levels of constant speed, with their steady windows;
- :mod:`~twin_cosim.servo.position_loop`: the position loop's tests, ``twin step`` (the position
  step and settling test: rise time, overshoot, settling time to a band, the tail) and
  ``twin kv`` (the following error against speed and the position-loop gain Kv it gives);
- :mod:`~twin_cosim.servo.friction`: ``twin friction``, the friction curve from constant-speed
  runs (of the twin, or measured), fitted to Coulomb, viscous and Stribeck terms per direction,
  written as ``plant.yaml``.

The frequency-domain figures (margins, closed loops, sensitivity, dynamic stiffness) are
:mod:`twin_cosim.frequency`'s.
"""
