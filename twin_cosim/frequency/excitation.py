"""Multisine excitations: log-spaced lines on the DFT grid, random phases, flat amplitude.

A period of N samples at the period T excites the lines k / (N T) Hz of a set of bins k, so
that a whole period in the window leaks nothing. The bins are log-spaced from the lowest
frequency up to the Nyquist frequency (bin N / 2, excited with a random sign), at most
``lines_per_decade`` per decade and never twice the same.

A loop that injects at the speed-loop rate while the position loop samples every R speed
samples folds each line f onto the images m / (R T) +- f. Two excited lines whose bins agree
modulo N / R, or add up to a multiple of it, would respond to each other; the bins are chosen so
that none do (``fold``), and a linear twin then gives coherence 1 at every line.

Each realisation draws new phases (uniform), so that averaging over realisations turns the
response to what is not linear into noise, which the coherence shows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LINES_PER_DECADE = 100


@dataclass(frozen=True)
class Multisine:
    """The lines and amplitude of a multisine.

    Attributes
    ----------
    samples : int
        Samples per period N.
    period : float
        Sample period T, s.
    bins : numpy.ndarray
        Excited DFT bins k (frequencies k / (N T)), increasing.
    amplitude : float
        Amplitude of every line, in the unit of the injected signal.
    """

    samples: int
    period: float
    bins: np.ndarray
    amplitude: float

    @property
    def frequency_hz(self) -> np.ndarray:
        """The excited frequencies, Hz."""
        return self.bins / (self.samples * self.period)

    def realisation(self, rng: np.random.Generator) -> np.ndarray:
        """One period with random phases (uniform; a random sign at the Nyquist bin)."""
        spectrum = np.zeros(self.samples // 2 + 1, dtype=np.complex128)
        phases = rng.uniform(0.0, 2 * math.pi, len(self.bins))
        # irfft: a bin k < N/2 of value N/2 exp(j phi) is cos(2 pi k n / N + phi); bin N/2 of
        # value N is (-1)^n
        spectrum[self.bins] = self.samples / 2 * np.exp(1j * phases)
        if self.bins[-1] == self.samples // 2:
            spectrum[-1] = self.samples * (1.0 if math.cos(phases[-1]) >= 0 else -1.0)
        return self.amplitude * np.fft.irfft(spectrum, self.samples)


def choose_bins(
    samples: int, low_bin: int, fold: int, lines_per_decade: int = LINES_PER_DECADE
) -> np.ndarray:
    """Log-spaced bins from ``low_bin`` to the Nyquist bin, none the image of another.

    ``fold`` is the period of the images in bins (N / R, or N when nothing folds): no two bins
    agree modulo it, nor add up to a multiple of it.
    """
    nyquist = samples // 2
    count = round(lines_per_decade * math.log10(nyquist / low_bin)) + 1
    targets = np.unique(np.round(np.geomspace(low_bin, nyquist, max(count, 2))).astype(int))
    residues: set[int] = set()
    chosen = []
    for target in targets:
        reach = max(1, int(0.01 * target))  # look this far either side of the target
        for k in sorted(range(target - reach, target + reach + 1), key=lambda b: abs(b - target)):
            own = {k % fold, -k % fold}
            if low_bin <= k <= nyquist and k not in chosen and not own & residues:
                residues |= own
                chosen.append(k)
                break
    return np.array(sorted(chosen))


def multisine(
    samples: int,
    period: float,
    low_hz: float,
    rms: float,
    fold: int,
    lines_per_decade: int = LINES_PER_DECADE,
) -> Multisine:
    """A multisine of ``samples`` per period at ``period`` (s) from ``low_hz`` (Hz) up.

    ``rms`` is the RMS value of the whole signal (unit of the injected signal); ``fold`` as
    :func:`choose_bins`.
    """
    low_bin = max(1, math.ceil(low_hz * samples * period - 1e-9))
    bins = choose_bins(samples, low_bin, fold, lines_per_decade)
    nyquist = int(bins[-1] == samples // 2)  # a line of mean square a^2, the others a^2 / 2
    return Multisine(samples, period, bins, rms / math.sqrt((len(bins) - nyquist) / 2 + nyquist))
