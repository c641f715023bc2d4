"""A controller set: the six tuned parameters and what it changes of the fixed settings.

A tuner sets more than the six parameters of eq. (7): ``twin autotune`` also sets the
current-setpoint filters and the feedforwards (gains and the inertia they assume), and a
campaign may tune filter frequencies. A :class:`ControllerSet` carries both; applied to a
scenario's settings it overrides only what it names, so the plant facts of each scenario stay
its own. As a file (YAML or JSON, what ``twin autotune --json`` prints)::

    params: {Kp_pos: 80.0, Kp_vel: 0.35, Ki_vel: 0.004, PP2: 0.72, PP3: 0.0082, f_H: 0.13}
    settings:                       # optional: fields of ControllerSettings
      inertia: 7.1e-4
      filters: [{type: notch, frequency_hz: 109.5, bandwidth_hz: 60.0, depth_db: -20.0}]
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings, TunedParameters


@dataclass(frozen=True)
class ControllerSet:
    """Tuned parameters and overrides of the fixed settings.

    Attributes
    ----------
    tuned : TunedParameters
        The six parameters.
    overrides : dict
        Field of :class:`~twin_cosim.controller.ControllerSettings` -> value (``filters``: a
        tuple of sections); none: the scenario's settings as they are.
    """

    tuned: TunedParameters
    overrides: Mapping[str, Any] = field(default_factory=dict)

    def settings_for(self, settings: ControllerSettings) -> ControllerSettings:
        """``settings`` with this set's overrides."""
        return dataclasses.replace(settings, **self.overrides) if self.overrides else settings

    def as_dict(self) -> dict[str, Any]:
        """The file's content: ``params`` and, when there are overrides, ``settings``."""
        data: dict[str, Any] = {"params": self.tuned.as_dict()}
        if self.overrides:
            settings = dict(self.overrides)
            if "filters" in settings:
                settings["filters"] = [current_filters.as_dict(f) for f in settings["filters"]]
            data["settings"] = settings
        return data
