"""Sim-to-real gap diagnosis: where the twin and the measured machine disagree, which unmodelled
effect causes it, and how much the gap shrinks once that effect is modelled."""
