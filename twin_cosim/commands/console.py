"""What the commands of ``twin`` write for the user: JSON files and warnings on stderr."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from twin_cosim.scenario import Scenario


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as indented JSON."""
    path.write_text(json.dumps(data, indent=2) + "\n")


def command_line(name: str) -> str:
    """The command line of ``twin NAME`` as typed (when this process is that command), for the
    files that say what made them; ``twin NAME`` otherwise."""
    if len(sys.argv) > 1 and sys.argv[1] == name:
        return shlex.join(["twin", *sys.argv[1:]])
    return f"twin {name}"


def warn_plant_mismatch(scenario: Scenario, fmu: Path | None) -> list[str]:
    """Warn on stderr when ``--plant`` is another model than the scenario's; the warnings."""
    from twin_cosim.scenario import plant_mismatch  # heavy: not at start (twin --help)

    warning = None if fmu is None else plant_mismatch(scenario, fmu)
    if warning is None:
        return []
    print(f"twin: warning: {warning}", file=sys.stderr)
    return [warning]
