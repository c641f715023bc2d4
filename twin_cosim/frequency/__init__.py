"""Frequency responses and loop design on the twin, as a drive makes them.

- :mod:`~twin_cosim.frequency.linear`: the linear two-mass plant, eqs. (1)-(4) of the paper, and
  the cascade linearised at its sample rates (plant with zero-order hold, speed PI,
  current-setpoint filters, position P);
- :mod:`~twin_cosim.frequency.measurement`: a frequency response measured on the twin in closed
  loop (multisines, the master with the excitation injected, H1 estimates and coherence), the
  response and the loops a drive measures;
- :mod:`~twin_cosim.frequency.margins`: gain and phase margins, crossover, bandwidth, peak
  sensitivity, from data and (python-control) from a linear system;
- :mod:`~twin_cosim.frequency.bode`: ``twin bode`` (measure, compare, write) and the Bode and
  Nyquist figures;
- :mod:`~twin_cosim.frequency.calibration`: ``twin calibrate``: FRF files (CSV) and their checks,
  the two-mass fit to a plant FRF, the fit as ``plant.yaml``;
- :mod:`~twin_cosim.frequency.autotune`: ``twin autotune``, an industrial FRF tuner, and the
  tuner on a scenario.
"""
