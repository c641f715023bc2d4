"""The effect library as the diagnosis sees it: the hypotheses of a plant model's card.

The hypotheses themselves (fitted parameters with units and bounds, the FMU parameters they set)
are declared in each model's ``models/<model>/card.yaml`` and read by
:mod:`twin_cosim.plant_model`; this module adds what the diagnosis needs around them: the orders
of periodic effects when the data show none, the refusal of a model without a library, and the
encoder resolution read off a measured position.
"""

from __future__ import annotations

import numpy as np

from twin_cosim.hypotheses import Hypothesis
from twin_cosim.plant_model import PlantModelError, plant_model

# Orders of periodic effects when the data show none (the diagnosis takes them from the
# residual's order spectra; twin synth uses them when an effect is given without ``order``).
DEFAULT_CONTEXT: dict[str, float] = {"motor_order": 6.0, "screw_order": 1.0}


class UnknownModelError(ValueError):
    """No hypothesis library for a plant model."""


def library_for(model_identifier: str) -> tuple[Hypothesis, ...]:
    """The hypotheses of a plant model (its FMU's modelIdentifier).

    Raises
    ------
    UnknownModelError
        For a model without a card (the diagnosis cannot guess what another plant's effects
        are called).
    """
    try:
        return plant_model(model_identifier).hypotheses
    except PlantModelError as exc:
        raise UnknownModelError(
            f"no hypothesis library for plant model {model_identifier!r}: {exc} "
            "(each model's library is its models/<model>/card.yaml)"
        ) from exc


def estimate_resolution(x: np.ndarray) -> float:
    """The grid step of a quantised position signal (m), 0.0 when the signal is not on a grid.

    The most common non-zero step between consecutive samples is taken as the resolution when
    every step is (within 1 %) a whole multiple of it.
    """
    steps = np.abs(np.diff(x))
    steps = steps[steps > 1e-15]
    if len(steps) < 10:
        return 0.0
    smallest = np.quantile(steps, 0.01)
    multiples = steps / smallest
    if np.all(np.abs(multiples - np.round(multiples)) < 0.01):
        return float(smallest)
    return 0.0
