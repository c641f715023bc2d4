"""Current-filter parameters tuned with the six: extra dimensions named in ``optimize.bounds``.

A bound named ``filter<k>.<parameter>`` tunes that parameter of the k-th section (from 1) of the
scenario's ``controller.settings.filters``, e.g.::

    optimize:
      bounds:
        filter1.frequency_hz: [80.0, 160.0]     # Hz
        filter1.depth_db: [-30.0, -3.0]         # dB

Such dimensions follow the six of eq. (7), in the order the bounds name them; without them a
campaign tunes exactly the six (its records and results unchanged). A candidate's filter values
replace those of the section in every case's settings.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Sequence

import numpy as np

from twin_cosim import current_filters
from twin_cosim.controller import ControllerSettings
from twin_cosim.current_filters import CurrentFilter

NAME = re.compile(r"filter(\d+)\.(\w+)")


@dataclasses.dataclass(frozen=True)
class FilterDimension:
    """One tuned filter parameter.

    Attributes
    ----------
    name : str
        ``filter<k>.<parameter>``.
    section : int
        Index of the section in the settings' filters (from 0).
    parameter : str
        A field of that section (frequency_hz, bandwidth_hz, depth_db, damping).
    """

    name: str
    section: int
    parameter: str


def parse_dimension(name: str, filters: Sequence[CurrentFilter]) -> FilterDimension | None:
    """The filter dimension a bound's name stands for; None when it names none.

    Raises
    ------
    ValueError
        When the name has the form but no such section or parameter exists.
    """
    match = NAME.fullmatch(name)
    if match is None:
        return None
    index, parameter = int(match.group(1)), match.group(2)
    if not 1 <= index <= len(filters):
        raise ValueError(
            f"{name}: controller.settings.filters has {len(filters)} section(s); "
            "filter<k> counts them from 1"
        )
    section = filters[index - 1]
    fields = [f.name for f in dataclasses.fields(section)]
    if parameter not in fields:
        raise ValueError(f"{name}: a {section.kind} has the parameters {fields}")
    return FilterDimension(name, index - 1, parameter)


def check_bounds(
    dimension: FilterDimension, bounds: tuple[float, float], settings: ControllerSettings
) -> None:
    """ValueError unless the section is valid at both bounds (as the filters check it)."""
    for value in bounds:
        with_filters(settings, [dimension], np.array([value]))


def with_filters(
    settings: ControllerSettings, dimensions: Sequence[FilterDimension], values: np.ndarray
) -> ControllerSettings:
    """``settings`` with the dimensions' sections set to ``values``.

    Raises
    ------
    ValueError
        When a value makes an invalid section (e.g. a frequency above the Nyquist frequency).
    """
    if not dimensions:
        return settings
    filters = list(settings.filters)
    for dimension, value in zip(dimensions, values, strict=True):
        if dimension.section >= len(filters):
            raise ValueError(
                f"{dimension.name}: these settings have only {len(filters)} filter section(s)"
            )
        filters[dimension.section] = dataclasses.replace(
            filters[dimension.section], **{dimension.parameter: float(value)}
        )
    current_filters.check_below_nyquist(filters, settings.speed_period)
    return dataclasses.replace(settings, filters=tuple(filters))


def start_values(settings: ControllerSettings, dimensions: Sequence[FilterDimension]) -> np.ndarray:
    """The dimensions' values in ``settings`` (the campaign's start)."""
    return np.array([getattr(settings.filters[d.section], d.parameter) for d in dimensions])
