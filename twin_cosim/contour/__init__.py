"""Contouring: a machine of several axes, part programs, the circular test (ISO 230-4).

- :mod:`~twin_cosim.contour.path`: the programmed path (lines and arcs) and the distance to it;
- :mod:`~twin_cosim.contour.gcode`: part programs (a G-code subset) to path blocks;
- :mod:`~twin_cosim.contour.interpolation`: the feed profile, per-axis references at 4 ms;
- :mod:`~twin_cosim.contour.machine_run`: a machine run on the master
  (:func:`twin_cosim.cosim.run_axes`), its contour record, metrics and figure;
- :mod:`~twin_cosim.contour.circle`: the circular test: its motion and run, the ISO 230-4
  figures and signatures, the polar plot, ``twin circle``'s files;
- :mod:`~twin_cosim.contour.measured_circle`, :mod:`~twin_cosim.contour.measured_circle`:
  measured circular tests, their replay and per-axis diagnosis, virtual X-Y machines;
- :mod:`~twin_cosim.contour.tuning`: tuning every axis for contours (a problem of the campaign
  driver);
- :mod:`~twin_cosim.contour.ssp`: the multi-axis plant as an SSP package.
"""
