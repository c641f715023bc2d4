"""Stage 2 of a diagnosis: what noise and calibration error alone make of a residual (the noise
harmonics and floors, the calibration floor) and the statistics of a gap and of an improvement
beyond them."""
