"""Controller sets: the six tuned parameters and what a set changes of the fixed settings; the
sets the paper publishes.

A tuner sets more than the six parameters of eq. (7): ``twin autotune`` also sets the
current-setpoint filters and the feedforwards (gains and the inertia they assume), and a
campaign may tune filter frequencies. A :class:`ControllerSet` carries both; applied to a
scenario's settings it overrides only what it names, so the plant facts of each scenario stay
its own. As a file (YAML or JSON, what ``twin autotune --json`` prints)::

    params: {Kp_pos: 80.0, Kp_vel: 0.35, Ki_vel: 0.004, PP2: 0.72, PP3: 0.0082, f_H: 0.13}
    settings:                       # optional: fields of ControllerSettings
      inertia: 7.1e-4
      filters: [{type: notch, frequency_hz: 109.5, bandwidth_hz: 60.0, depth_db: -20.0}]

**The paper's sets** (Haber Guerra et al., IEEE Access 2020): Table 3 lists the six tuned parameters
K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] of the industrial Fine-Tune method (FT, also eq. (8))
and of the three optimizers. Units as in :mod:`twin_cosim.controller`.
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


TABLE3: dict[str, TunedParameters] = {
    "ft": TunedParameters(
        Kp_pos=66.6667, Kp_vel=0.2865, Ki_vel=0.0080, PP2=0.7184, PP3=0.0082, f_H=0.1288
    ),
    "ga": TunedParameters(
        Kp_pos=74.8709, Kp_vel=0.3008, Ki_vel=0.00151, PP2=0.3012, PP3=0.03097, f_H=0.02605
    ),
    "ce": TunedParameters(
        Kp_pos=74.5483, Kp_vel=0.4976, Ki_vel=0.0028, PP2=0.1085, PP3=0.0437, f_H=0.0262
    ),
    "sa": TunedParameters(
        Kp_pos=64.4926, Kp_vel=0.4970, Ki_vel=0.00305, PP2=0.1715, PP3=0.0695, f_H=0.0006
    ),
}
FINE_TUNE = TABLE3["ft"]


def set_name(tuned: TunedParameters) -> str:
    """The name the tables give a scenario's own set: the paper's (FT, GA, CE, SA) or "the
    scenario's set"."""
    named = [name.upper() for name, values in TABLE3.items() if values == tuned]
    return f"{named[0]} (the scenario's set)" if named else "the scenario's set"
