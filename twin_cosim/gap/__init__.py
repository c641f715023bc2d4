"""Sim-to-real gap diagnosis: where the twin and the measured machine disagree, which unmodelled
effect causes it, and how much the gap shrinks once that effect is modelled.

The pipeline (:mod:`twin_cosim.gap.diagnosis`) runs its stages, each in its own sub-package:
``data`` (the measured runs checked and split, their residuals), ``floors`` (the noise and
calibration floors and the statistics against them), ``where`` (regimes, along the axis,
spectra), ``which`` (the selection of effects: the acceptance rule, the replays and fits, the
selector) and ``report`` (the verdict, the pages and their figures). ``settings`` holds the
thresholds of all of them; ``synth`` is the virtual machine whose answer is known.
"""
