"""The one YAML loader and the one checker of every input file the twin reads; the reader of
JSON-lines files (a campaign's evaluation log, the watch's log).

Scenarios, their ``optimize`` and ``diagnose`` sections, plant parameter files (``plant.yaml``)
and plant-model cards are all read by :func:`load_yaml` and checked with :class:`Checker`, so that
a value reads the same everywhere (``2e-5`` is a float in each of them) and every error names the
file, the key path and what was expected.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import yaml


class ScenarioError(ValueError):
    """An input file is invalid; the message names the file, the key and what was expected."""


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """YAML loader (libyaml's parser where PyYAML has it: ten times faster) that also reads 1e6
    and 2.5e-3 (no dot or no exponent sign) as floats."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"^[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?$|^[-+]?\.(?:inf|Inf|INF)$|^\.(?:nan|NaN|NAN)$"
    ),
    list("-+0123456789."),
)


def json_lines(
    lines: Iterable[str], corrupt: Callable[[int, json.JSONDecodeError], str]
) -> Iterator[tuple[int, Any]]:
    """The values of a JSON-lines text, one a line, with their line numbers (from 1); blank lines
    are skipped. A line that is not JSON raises ``ValueError`` with ``corrupt(number, error)``
    (the message names the file and the line)."""
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            yield number, json.loads(line)
        except json.JSONDecodeError as exc:
            raise ValueError(corrupt(number, exc)) from None


def load_yaml(path: Path | str, error: type[Exception] = ScenarioError) -> Any:
    """Read a YAML file; ``error`` names the file on a read or syntax error."""
    try:
        return yaml.load(Path(path).read_text(), Loader=_Loader)  # noqa: S506 - a SafeLoader subclass
    except FileNotFoundError as exc:
        raise error(f"{path}: file not found") from exc
    except IsADirectoryError as exc:
        raise error(f"{path}: is a folder, not a YAML file") from exc
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a text (YAML) file: {exc}") from exc
    except OSError as exc:
        raise error(f"{path}: cannot read: {exc.strerror or exc}") from exc
    except yaml.YAMLError as exc:
        raise error(f"{path}: malformed YAML: {exc}") from exc


class Checker:
    """Checks of values read from one file; each failure names the file and the key path.

    Parameters
    ----------
    source
        The file the values come from (named in every error).
    error
        The exception class raised (a subclass of ValueError).
    prefix
        Key path put before every key named in errors (``axes.X.``: the section of one axis).
    """

    def __init__(
        self, source: Path | str, error: type[Exception] = ScenarioError, prefix: str = ""
    ) -> None:
        self.source = source
        self.error = error
        self.prefix = prefix

    def within(self, key: str) -> Checker:
        """A checker of the same file for the values under ``key`` (their keys named in full)."""
        return Checker(self.source, self.error, f"{self.prefix}{key}.")

    def where(self, key: str) -> str:
        """The file and full key path of ``key``, as errors name them."""
        return f"{self.source}: {self.prefix}{key}"

    def fail(self, key: str, expected: str, got: Any = None) -> Exception:
        """The error for ``key``: what was expected and, when given, what was found."""
        suffix = "" if got is None else f", got {got!r}"
        return self.error(f"{self.where(key)}: expected {expected}{suffix}")

    def mapping(self, value: Any, key: str, allowed: set[str] | None = None) -> dict[str, Any]:
        """A mapping (None reads as empty) whose keys are among ``allowed`` when given."""
        if value is None:
            return {}
        if not isinstance(value, dict):
            raise self.fail(key, "a mapping", value)
        if allowed is not None:
            unknown = sorted(set(value) - allowed)
            if unknown:
                raise self.error(
                    f"{self.where(key)}: unknown key(s) {unknown}; allowed: {sorted(allowed)}"
                )
        return value

    def number(
        self, value: Any, key: str, minimum: float | None = None, positive: bool = False
    ) -> float:
        """A finite number (not a bool), > 0 when ``positive``, >= ``minimum`` when given."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, "a number", value)
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(key, "a finite number", value)
        if positive and value <= 0:
            raise self.fail(key, "a number > 0", value)
        if minimum is not None and value < minimum:
            raise self.fail(key, f"a number >= {minimum}", value)
        return value

    def text(self, value: Any, key: str) -> str:
        """A non-empty string."""
        if not isinstance(value, str) or not value:
            raise self.fail(key, "a text", value)
        return value

    def names(self, value: Any, key: str) -> tuple[str, ...]:
        """A list of names (strings)."""
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(key, "a list of names", value)
        return tuple(value)
