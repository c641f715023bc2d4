"""Contouring: a machine of several axes, part programs, the circular test (ISO 230-4).

- :mod:`~twin_cosim.contour.lockstep`: the master stepping the axes' FMU instances in lockstep;
- :mod:`~twin_cosim.contour.path`: the programmed path (lines and arcs) and the distance to it;
- :mod:`~twin_cosim.contour.gcode`: part programs (a G-code subset) to path blocks;
- :mod:`~twin_cosim.contour.interpolation`: the feed profile, per-axis references at 4 ms;
- :mod:`~twin_cosim.contour.machine_run`: a machine run, its contour record and metrics;
  :mod:`~twin_cosim.contour.contour_plot`: its figure;
- :mod:`~twin_cosim.contour.circle_test`, :mod:`~twin_cosim.contour.iso230`,
  :mod:`~twin_cosim.contour.polar_plot`, :mod:`~twin_cosim.contour.circle_report`: the circular
  test;
- :mod:`~twin_cosim.contour.measured_circle`, :mod:`~twin_cosim.contour.circle_diagnosis`:
  measured circular tests, their replay and per-axis diagnosis, virtual X-Y machines;
- :mod:`~twin_cosim.contour.tuning`: tuning every axis for contours (a problem of the campaign
  driver);
- :mod:`~twin_cosim.contour.ssp`: the multi-axis plant as an SSP package.
"""
