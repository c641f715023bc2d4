"""Scenarios shipped with the package, found by name (``reference1``) as well as by path."""

from __future__ import annotations

from pathlib import Path

from twin_cosim.schema import ScenarioError

_PACKAGE = Path(__file__).resolve().parents[1]


def packaged_scenarios_dir() -> Path:
    """The shipped scenarios: ``twin_cosim/scenarios`` of a wheel, else ``scenarios/``."""
    packaged = _PACKAGE / "scenarios"
    return packaged if packaged.is_dir() else _PACKAGE.parent / "scenarios"


def find_scenario(spec: Path | str) -> Path:
    """A scenario file from a path, or from the name of a shipped scenario (``reference1``).

    Raises
    ------
    ScenarioError
        When ``spec`` is neither an existing file nor the name of a shipped scenario.
    """
    path = Path(spec)
    if path.is_file() or path.suffix or len(path.parts) > 1:
        return path
    shipped = packaged_scenarios_dir() / f"{path.name}.yaml"
    if shipped.is_file():
        return shipped
    names = sorted(p.stem for p in packaged_scenarios_dir().glob("*.yaml"))
    raise ScenarioError(f"{spec}: neither a scenario file nor a shipped scenario {names}")
