"""The six tuned parameters: ``controller.parameters`` of a scenario and ``--params``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from twin_cosim import paper
from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.schema import ScenarioError, load_yaml


def tuned_section(data: Any, where: str) -> TunedParameters:
    """Tuned parameters from a mapping, or the name of a set of the paper's Table 3."""
    if isinstance(data, str):
        if data.lower() not in paper.TABLE3:
            raise ScenarioError(
                f"{where}: expected the six parameters or a set of Table 3 {sorted(paper.TABLE3)}"
                f", got {data!r}"
            )
        return paper.TABLE3[data.lower()]
    return tuned_from_mapping(data, where)


def tuned_from_mapping(data: Any, where: str) -> TunedParameters:
    """The six tuned parameters from a mapping that must hold exactly those names.

    Raises
    ------
    ScenarioError
        Naming ``where`` (file and key) on a missing, unknown or invalid value.
    """
    if not isinstance(data, dict):
        raise ScenarioError(f"{where}: expected a mapping of {list(TUNED_NAMES)}")
    missing = [n for n in TUNED_NAMES if n not in data]
    unknown = sorted(set(data) - set(TUNED_NAMES))
    if missing or unknown:
        raise ScenarioError(
            f"{where}: missing {missing}, unknown {unknown}; expected exactly {list(TUNED_NAMES)}"
        )
    values = {}
    for name in TUNED_NAMES:
        value = data[name]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ScenarioError(f"{where}.{name}: expected a number, got {value!r}")
        values[name] = float(value)
    try:
        return TunedParameters(**values)
    except ValueError as exc:
        raise ScenarioError(f"{where}: {exc}") from exc


def load_tuned_parameters(spec: str) -> TunedParameters:
    """Parameters for ``--params``: a Table 3 set name (ft, ga, ce, sa) or a YAML/JSON file.

    The file holds the six names at the top level or under ``best_params`` (the summary that
    ``twin optimize`` writes).
    """
    if spec.lower() in paper.TABLE3:
        return paper.TABLE3[spec.lower()]
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(
            f"--params {spec}: neither a set of Table 3 {sorted(paper.TABLE3)} nor a file"
        )
    data = load_yaml(path)
    if isinstance(data, dict) and "best_params" in data:
        return tuned_from_mapping(data["best_params"], f"{path}: best_params")
    return tuned_from_mapping(data, str(path))


def load_axes_parameters(spec: str, axes: tuple[str, ...]) -> dict[str, TunedParameters]:
    """Parameters of each axis of a machine for ``--params``.

    A Table 3 set name, or a file of one set, gives every axis that set; a file with ``axes:``
    (``{X: {Kp_pos: ...}, Y: {...}}``, at the top level or under ``best_params``: what a contour
    campaign writes) gives each axis its own, the axes it does not name keep theirs.
    """
    if spec.lower() in paper.TABLE3:
        return dict.fromkeys(axes, paper.TABLE3[spec.lower()])
    path = Path(spec)
    if not path.is_file():
        raise ScenarioError(
            f"--params {spec}: neither a set of Table 3 {sorted(paper.TABLE3)} nor a file"
        )
    data = load_yaml(path)
    where = str(path)
    if isinstance(data, dict) and "best_params" in data:
        data, where = data["best_params"], f"{path}: best_params"
    if not (isinstance(data, dict) and "axes" in data):
        return dict.fromkeys(axes, tuned_from_mapping(data, where))
    given = data["axes"]
    if not isinstance(given, dict) or not set(given) <= set(axes):
        raise ScenarioError(f"{where}: axes: expected a mapping of the machine's axes {list(axes)}")
    return {name: tuned_from_mapping(given[name], f"{where}: axes.{name}") for name in given}
