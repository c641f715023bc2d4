"""Parameter sets published in the paper (Haber Guerra et al., IEEE Access 2020).

Table 3 lists the six tuned parameters K = [Kp_pos, Kp_vel, Ki_vel, PP2, PP3, f_H] of the
industrial Fine-Tune method (FT, also eq. (8)) and of the three optimizers. Units as in
:mod:`twin_cosim.controller`.
"""

from __future__ import annotations

from twin_cosim.controller import TunedParameters

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
