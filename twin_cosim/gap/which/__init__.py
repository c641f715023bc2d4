"""Stage 4 of a diagnosis: which effects explain the gap. The acceptance rule and the held-out
runs it judges on, the replays and fits on the worker pool, and the selector that runs the
rounds, the pair screen, the cold refits, the swaps and the backward pass."""
