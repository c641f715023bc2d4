"""What the steps of a selection (the pair screen, the swaps, the backward pass, the cold
refits) use of the selector that runs them: a protocol, so that those steps do not import the
selector that imports them."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import numpy as np

    from twin_cosim.gap.floors.calibration import CalibrationBasis
    from twin_cosim.gap.settings import DiagnosisSettings
    from twin_cosim.gap.which.acceptance import Judging
    from twin_cosim.gap.which.replay import JointFitTask, Replays
    from twin_cosim.gap.which.rounds import Accepted
    from twin_cosim.hypotheses import Hypothesis


class SelectorView(Protocol):
    """The selector's state and services a selection step reads
    (:class:`twin_cosim.gap.selection.Selector` offers them).

    Attributes
    ----------
    library : dict of str to Hypothesis
        The model's effects by name.
    judging : Judging
        The held-out runs and the acceptance tests.
    settings : DiagnosisSettings
        The diagnosis' effort and levels.
    train_seconds : float
        Length of the training data, s.
    """

    library: dict[str, Hypothesis]
    judging: Judging
    settings: DiagnosisSettings
    train_seconds: float

    def tasks(self, phase: str, tasks: list[Any]) -> list[Any]:
        """Results of ``tasks`` run on the pool, in task order, timed under ``phase``."""
        ...

    def left(self, overrides: dict[str, float], replays: Replays) -> np.ndarray:
        """The normalised held-out residual the best calibration correction leaves."""
        ...

    def basis(self, base: dict[str, float]) -> CalibrationBasis:
        """Calibration directions around the parameter set ``nominal + base``."""
        ...

    def joint(
        self, accepted: list[Accepted], sequential: dict[str, float]
    ) -> tuple[dict[str, float], Replays]:
        """The accepted effects' parameters (refitted together when that judges better than
        ``sequential``) and their replays."""
        ...

    def refit_task(self, accepted: list[Accepted]) -> JointFitTask:
        """The joint refit of ``accepted`` on the training data."""
        ...

    def size_above_tolerance(
        self, hypothesis: Hypothesis, values: tuple[float, ...], base: dict[str, float]
    ) -> bool:
        """Whether a fitted change of a calibrated parameter exceeds its tolerance."""
        ...
