"""Judgement of a closed-loop run: did the loop diverge or oscillate (a limit cycle, a chattering
current, :mod:`twin_cosim.oscillation`), did the current sit at its limit."""

from __future__ import annotations

from typing import TYPE_CHECKING

from twin_cosim.optimize.config import load_config
from twin_cosim.oscillation import record_findings
from twin_cosim.scenario import Scenario

if TYPE_CHECKING:
    from twin_cosim.run_record import RunRecord

SATURATED_SHARE = 0.1  # a current at its limit longer than this share of the run is a warning


def loop_warnings(record: RunRecord, scenario: Scenario) -> tuple[bool, list[str]]:
    """Whether a run is unusable (it diverged, or oscillates), and warnings about it.

    Parameters
    ----------
    record
        The run of :func:`twin_cosim.cosim.run_scenario`: ``error`` (m) and ``current`` (A).
    scenario
        The scenario it ran: its ``optimize.abort_error_um`` (um) is the band, its
        ``current_limit`` (A) the limit.

    Returns
    -------
    tuple
        Unusable: |error| beyond ``optimize.abort_error_um``, a limit cycle or a chattering
        current; and the warnings: each of those, and a current at its limit more than 10 % of
        the time.
    """
    band_um = load_config(scenario).abort_error_um
    peak_um = float(abs(record["error"]).max()) * 1e6
    limit = scenario.settings.current_limit
    saturated = float((abs(record["current"]) >= 0.999 * limit).mean())
    found = []
    diverged = not peak_um <= band_um
    if diverged:
        found.append(
            f"the loop diverged: |error| reached {peak_um:.4g} um, beyond the band of "
            f"{band_um:g} um (optimize.abort_error_um) in which the optimizer keeps a run"
        )
    oscillating = [] if diverged else record_findings(record, limit)
    found.extend(oscillating)
    if saturated > SATURATED_SHARE:
        found.append(f"the current is at its limit ({limit:g} A) {saturated:.0%} of the time")
    return diverged or bool(oscillating), found
