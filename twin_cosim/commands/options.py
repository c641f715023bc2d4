"""Options and argument types shared by the commands of ``twin``, and their help format."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from twin_cosim.environment import DATA_ENV

if TYPE_CHECKING:
    from twin_cosim.scenario import Scenario


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


SCENARIO_HELP = "scenario YAML file, or the name of a shipped one"


def scenario_parser(
    subparsers,
    name: str,
    help: str,
    handler: Callable[[argparse.Namespace], int],
    scenario: str = SCENARIO_HELP,
) -> argparse.ArgumentParser:
    """The parser of a command on a scenario, run by ``handler``: its ``scenario`` argument
    (``scenario``: its help), the command's own options follow (a test of an axis then ends with
    :func:`axis_test_options`)."""
    parser = command_parser(subparsers, name, help, handler)
    parser.add_argument("scenario", help=scenario)
    return parser


def number_options(
    parser: argparse.ArgumentParser,
    table: tuple[tuple[str, Callable[[str], float], float | None, str, str], ...],
) -> None:
    """Options of one number each: (option, type, default, metavar, help) per row."""
    for option, kind, default, metavar, text in table:
        parser.add_argument(option, type=kind, default=default, metavar=metavar, help=text)


def quiet_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--quiet``: ``what`` the command then leaves out (its help)."""
    parser.add_argument("--quiet", action="store_true", help=what)


def budget_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--budget N``: evaluations of a campaign's method (``what``: its help)."""
    parser.add_argument("--budget", type=whole_number(1), help=what)


def pool_options(
    parser: argparse.ArgumentParser, workers: str, scheduler: str | None = None
) -> None:
    """``--workers N`` (``workers``: its help) and, for a command that may run on Dask,
    ``--scheduler ADDR`` (``scheduler``: its help)."""
    parser.add_argument("--workers", type=whole_number(1), help=workers)
    if scheduler is not None:
        parser.add_argument("--scheduler", metavar="ADDR", help=scheduler)


def coherence_option(parser: argparse.ArgumentParser, default: float, what: str) -> None:
    """``--coherence-floor``: the coherence below which a line of an FRF counts as noise, and
    ``what`` is done with such lines (its help)."""
    parser.add_argument("--coherence-floor", type=fraction(0.0, 1.0), default=default, help=what)


def axis_test_options(parser: argparse.ArgumentParser, folder: str) -> None:
    """What every test of an axis (``bode``, ``step``, ``kv``, ``friction``) takes besides its
    own: ``--params``, ``--plant``, ``--plant-parameters``, ``--out`` (default ``folder``),
    ``--json``, ``--no-plots``, ``--data``."""
    params_option(parser)
    plant_option(parser)
    plant_parameters_option(parser)
    output_options(parser, f"output folder (default: {folder})")
    no_plots_option(parser)
    data_option(parser)


FEED_OVERRIDE_RANGE = (1.0, 200.0)  # % (a CNC's feed override knob: SINUMERIK up to 120 %)


def _feed_override(text: str) -> float:
    low, high = FEED_OVERRIDE_RANGE
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(
            f"expected a feed override from {low:g} to {high:g} %, got {text!r}"
        )
    return value


def feed_override_option(parser: argparse.ArgumentParser) -> None:
    """``--feed-override PCT``: the programmed feeds scaled (rapid traverses keep theirs)."""
    parser.add_argument(
        "--feed-override",
        type=_feed_override,
        default=100.0,
        metavar="PCT",
        help="feed override, %% of every programmed feed, 1 to 200 (rapid traverses G00 keep "
        "the axes' speed) (default: 100)",
    )


def no_plots_option(parser: argparse.ArgumentParser) -> None:
    """``--no-plots``: write no figures (the results and data files are the same)."""
    parser.add_argument(
        "--no-plots",
        action="store_true",
        help="write no figures (PNG); every other file and the printed result are the same",
    )


def columns_option(parser: argparse.ArgumentParser) -> None:
    """``--columns``: the measured files' column names per signal."""
    parser.add_argument(
        "--columns",
        metavar="SIGNAL=NAME,...",
        help="column names of the measured files, per signal, e.g. x=ActPos,t=Time "
        "(docs/gap.md, Measured runs) (default: the scenario's measured_columns, else the "
        "signals' own names)",
    )


def column_map(args: argparse.Namespace, scenario: Scenario) -> dict[str, str]:
    """The column map of a command: the scenario's ``measured_columns``, ``--columns`` on top."""
    from twin_cosim.measured import parse_columns

    given = parse_columns(args.columns) if getattr(args, "columns", None) else {}
    return {**scenario.measured_columns, **given}
