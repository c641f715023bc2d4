"""Frequency responses and loop design on the twin, as a drive makes them.

- :mod:`~twin_cosim.frequency.two_mass`: the linear two-mass plant, eqs. (1)-(4) of the paper;
- :mod:`~twin_cosim.frequency.loops`: the cascade linearised at its sample rates (plant with
  zero-order hold, speed PI, current-setpoint filters, position P);
- :mod:`~twin_cosim.frequency.excitation`: multisines (log-spaced lines, random phases);
- :mod:`~twin_cosim.frequency.estimate`: H1 estimates and coherence over realisations;
- :mod:`~twin_cosim.frequency.measurement`: a closed-loop measurement on the twin (compiled);
- :mod:`~twin_cosim.frequency.response`: a frequency response and the loops measured;
- :mod:`~twin_cosim.frequency.margins`: gain and phase margins, crossover, bandwidth, peak
  sensitivity, from data and (python-control) from a linear system;
- :mod:`~twin_cosim.frequency.bode`: ``twin bode``: measure, compare, write;
- :mod:`~twin_cosim.frequency.frf_file`: FRF files (CSV) and their checks;
- :mod:`~twin_cosim.frequency.fit`: the two-mass parameters fitted to a plant FRF;
- :mod:`~twin_cosim.frequency.calibration`: ``twin calibrate``: the fit as ``plant.yaml``;
- :mod:`~twin_cosim.frequency.autotune`: ``twin autotune``, an industrial FRF tuner;
- :mod:`~twin_cosim.frequency.plots`: Bode and Nyquist figures.
"""
