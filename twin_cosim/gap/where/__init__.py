"""Stage 3 of a diagnosis: where the gap lies (regimes, spans along the axis) and whether it is
periodic in position or in time (order and frequency spectra)."""
