"""Stage 1 of a diagnosis: the data it works on (the measured runs checked and split, the plant
model's library), each sample's regime, and the residuals of the runs against the twin's
replays."""
