"""H1 estimates and coherence from periods recorded under different multisine realisations.

With the excitation d, a measured output y and, for the indirect (closed-loop) method, the
signal u at the input of what is measured, each recorded over one steady-state period per
realisation m, at an excited line::

    G_dy = sum_m Y_m conj(D_m),   G_dd = sum_m |D_m|^2,   G_yy = sum_m |Y_m|^2
    H1   = G_dy / G_dd                          (y over d)
    H    = G_dy / G_du                          (y over u, indirect: both from the same d)
    gamma^2 = |G_dy|^2 / (G_dd G_yy)            (coherence of y with d)

The indirect estimate measures what lies between u and y without the bias feedback gives a
direct estimate: d is the only signal both share. Its coherence is the smaller of those of y
and of u with d. In a linear, noise-free loop at steady state it is 1; noise, and the
response to what is not linear (which changes with every realisation), lower it.
"""

from __future__ import annotations

import numpy as np


def line_spectra(periods: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """DFT of each recorded period at the excited bins, shape (realisations, lines)."""
    return np.fft.rfft(periods, axis=-1)[:, bins]


def coherence(d: np.ndarray, y: np.ndarray) -> np.ndarray:
    """gamma^2 of y with d at each line, from line spectra (realisations, lines)."""
    cross = np.abs(np.sum(y * np.conj(d), axis=0)) ** 2
    power = np.sum(np.abs(d) ** 2, axis=0) * np.sum(np.abs(y) ** 2, axis=0)
    return np.divide(cross, power, out=np.zeros_like(cross), where=power > 0)


def ratio(d: np.ndarray, y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """y over u estimated through d (H1 of each over d), and its coherence, per line.

    Parameters
    ----------
    d, y, u
        Line spectra (realisations, lines) of the excitation, the output and the input.

    Returns
    -------
    tuple
        The complex estimate and the coherence (the smaller of y's and u's with d).
    """
    estimate = np.sum(y * np.conj(d), axis=0) / np.sum(u * np.conj(d), axis=0)
    return estimate, np.minimum(coherence(d, y), coherence(d, u))
