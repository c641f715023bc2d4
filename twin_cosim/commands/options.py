"""Options and argument types shared by the commands of ``twin``, and their help format."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path

from twin_cosim.environment import DATA_ENV


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help that shows every option's default: the value, or what the help text says it is;
    descriptions and epilogs keep their lines."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, argparse.SUPPRESS):
            return text
        if action.default is False:
            return f"{text} (default: off)"
        return f"{text} (default: %(default)s)"


def command_parser(
    subparsers, name: str, help: str, handler: Callable[[argparse.Namespace], int]
) -> argparse.ArgumentParser:
    """The parser of command ``name`` among ``subparsers`` (help shows the defaults); the
    command runs ``handler`` with the parsed arguments and exits with what it returns."""
    parser = subparsers.add_parser(name, help=help, formatter_class=HelpFormatter)
    parser.set_defaults(handler=handler)
    return parser


def whole_number(low: int) -> Callable[[str], int]:
    """An argparse type: a whole number >= ``low`` (the message names the option)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low:
            raise argparse.ArgumentTypeError(f"expected a whole number >= {low}, got {text!r}")
        return value

    return parse


def fraction(low: float, high: float) -> Callable[[str], float]:
    """An argparse type: a number in [low, high]."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"expected a number in [{low}, {high}], got {text!r}")
        return value

    return parse


def number_above(low: float, inclusive: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number > ``low`` (>= when ``inclusive``)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not math.isfinite(value) or value < low or (value == low and not inclusive):
            relation = ">=" if inclusive else ">"
            raise argparse.ArgumentTypeError(
                f"expected a finite number {relation} {low:g}, got {text!r}"
            )
        return value

    return parse


def params_option(parser: argparse.ArgumentParser) -> None:
    """``--params``: a controller set instead of the scenario's."""
    parser.add_argument(
        "--params",
        help="ft|ga|ce|sa (paper Table 3) or a YAML/JSON file: the six parameters, or what "
        "twin autotune or twin optimize wrote (with its filters and feedforwards) "
        "(default: the scenario's)",
    )


def output_options(parser: argparse.ArgumentParser, folder: str, printed: str = "summary") -> None:
    """``--out DIR`` (``folder``: what the folder is and its default, for the help) and
    ``--json`` (print the ``printed`` as one JSON object)."""
    parser.add_argument("--out", metavar="DIR", help=folder)
    parser.add_argument(
        "--json", action="store_true", help=f"print the {printed} as one JSON object"
    )


def out_folder(option: str | None, default: Path) -> Path:
    """The output folder of ``--out`` (or ``default``); an existing file is refused."""
    out = Path(option) if option else default
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a folder; give a folder")
    return out


def plant_path(args: argparse.Namespace) -> Path | None:
    """The FMU of ``--plant``, None when not given."""
    return Path(args.plant) if args.plant else None


def data_option(parser: argparse.ArgumentParser) -> None:
    """``--data DIR``: the folder of measured data files."""
    parser.add_argument(
        "--data",
        metavar="DIR",
        help=f"folder of measured data files, e.g. the EMPS benchmark's DATA_EMPS.mat "
        f"(default: ${DATA_ENV}, else the path in the scenario)",
    )


def plant_parameters_option(parser: argparse.ArgumentParser) -> None:
    """``--plant-parameters FILE``: a plant.yaml applied to every scenario."""
    parser.add_argument(
        "--plant-parameters",
        metavar="FILE",
        help="calibrated plant parameters for every scenario, the plant.yaml of twin diagnose "
        "(default: none)",
    )


def plant_option(parser: argparse.ArgumentParser) -> None:
    """``--plant FMU``: another plant than the scenario's."""
    parser.add_argument(
        "--plant",
        metavar="FMU",
        help="another FMU offering the plant contract (default: the scenario's plant)",
    )


def no_plots_option(parser: argparse.ArgumentParser) -> None:
    """``--no-plots``: write no figures (the results and data files are the same)."""
    parser.add_argument(
        "--no-plots",
        action="store_true",
        help="write no figures (PNG); every other file and the printed result are the same",
    )
