"""The machine as the judge of a tuned set: its E_pk, ITAE and IAU beside the twin's prediction,
and the prediction's interval: over what the twin's plant file leaves uncertain (its
intervals), widened by what the twin still missed on its held-out runs (its ``model_error``,
:mod:`twin_cosim.model_error`).

A machine is either

- a measured run (CSV or EMPS .mat, see :mod:`twin_cosim.measured`) made on the machine with the
  gains being judged, following the scenario's reference: its metrics come from the recorded
  error and current; or
- a virtual machine: a YAML file whose plant stands for the machine, either a scenario (its
  ``plant`` section: FMU and parameters, as ``twin synth`` switches effects on) or a plant
  parameter file (``model`` and ``parameters``; ``twin synth`` writes one, ``RUN.machine.yaml``),
  or the answer ``twin synth`` writes beside its run (``RUN.truth.json``: the parameters it
  changed from the scenario's plant). The scenario being simulated is run on that plant with
  the same gains; only the start position is the scenario's.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin_cosim.controller import TunedParameters
from twin_cosim.cosim import run_scenario
from twin_cosim.measured import check_against_reference, read_measured
from twin_cosim.metrics import Metrics, compute_metrics
from twin_cosim.optimize.config import UncertaintySet, relative_ranges
from twin_cosim.plant import Plant
from twin_cosim.plant_model import plant_model
from twin_cosim.run_record import RunRecord
from twin_cosim.scenario import Scenario, load_scenario
from twin_cosim.scenario.plant_parameters import check_values, read_plant_parameters
from twin_cosim.schema import ScenarioError, load_yaml

MEASURED_SUFFIXES = (".csv", ".mat")
JUDGED = ("E_pk_um", "ITAE", "IAU")
# Plant samples within a plant file's intervals behind a prediction's interval (beside the
# calibrated plant itself)
PREDICTION_SAMPLES = 16


def machine_scenario(scenario: Scenario, machine: Path) -> Scenario:
    """The scenario with the virtual machine's plant (FMU and parameters) in place of the twin's."""
    if machine.suffix.lower() == ".json":
        return dataclasses.replace(
            scenario,
            plant_parameters={**scenario.plant_parameters, **_truth_plant(scenario, machine)},
        )
    data = load_yaml(machine)
    if isinstance(data, dict) and "reference" in data:
        plant = load_scenario(machine)
        fmu, model, parameters = plant.fmu, plant.model, dict(plant.plant_parameters)
    else:
        fmu, model = scenario.fmu, scenario.model
        parameters = read_plant_parameters(machine, scenario.model_name()).parameters
    parameters["load_position_start"] = scenario.plant_parameters["load_position_start"]
    return dataclasses.replace(scenario, fmu=fmu, model=model, plant_parameters=parameters)


def _truth_plant(scenario: Scenario, truth: Path) -> dict[str, float]:
    """The plant parameters of the virtual machine ``twin synth`` recorded in ``RUN.truth.json``
    (those it changed from the scenario's nominal plant)."""
    try:
        data = json.loads(truth.read_text())
    except (UnicodeDecodeError, ValueError) as exc:
        raise ScenarioError(f"{truth}: not a twin synth answer (JSON): {exc}") from None
    values = data.get("plant_parameters") if isinstance(data, dict) else None
    if not isinstance(values, dict):
        raise ScenarioError(
            f"{truth}: plant_parameters: expected the mapping twin synth writes (RUN.truth.json)"
        )
    return check_values(values, scenario.model_name(), str(truth), "plant_parameters")


def machine_metrics(
    scenario: Scenario,
    tuned: TunedParameters,
    machine: Path | str,
    columns: Mapping[str, str] | None = None,
) -> tuple[Metrics, str]:
    """Metrics of ``tuned`` on the machine over the scenario's window, and the machine's kind;
    a measured run's columns named by ``columns`` (signal -> the file's column).

    Raises
    ------
    ValueError
        (ScenarioError, MeasuredDataError) naming the file when the machine cannot be read or a
        measured run does not follow the scenario's reference.
    """
    machine = Path(machine)
    if machine.suffix.lower() in MEASURED_SUFFIXES:
        run = read_measured(machine, columns)
        check_against_reference(run, scenario.reference)
        record = RunRecord.from_columns(
            {"t": run.t, "error": run.x_ref - run.x, "current": run.current},
            {"t": "s", "error": "m", "current": "A"},
        )
        return compute_metrics(record, scenario.metrics_window), "measured run"
    judged = machine_scenario(scenario, machine)
    with Plant(judged.plant_fmu()) as plant:
        record = run_scenario(plant, judged, tuned)
    return compute_metrics(record, scenario.metrics_window), "virtual machine"


def prediction(
    twin: Metrics,
    machine: Metrics,
    spread: list[Metrics] | None = None,
    margins: Mapping[str, float] | None = None,
) -> dict[str, dict[str, float]]:
    """Per judged metric: the machine's value, the twin's and the twin's relative error (%);
    with the twin's metrics on plant samples (``spread``, :func:`plant_samples`) or the margins
    of the twin's own error (``margins``, :func:`model_error_margins`), the prediction's
    interval and whether the machine's value lies ``inside`` it.

    The interval runs from the least to the largest of the twin's value and the samples'
    (``spread_low``, ``spread_high``), widened on both sides by the metric's margin
    (``margin``, 0 without one) and kept at or above 0 (every judged metric is): ``low``,
    ``high``."""
    found = {}
    for name in JUDGED:
        real, predicted = getattr(machine, name), getattr(twin, name)
        error = 100.0 * (predicted - real) / real if real else math.nan
        found[name] = {"machine": real, "twin": predicted, "relative_error_pct": error}
        if spread or margins:
            values = [predicted, *(getattr(m, name) for m in spread or [])]
            margin = (margins or {}).get(name, 0.0)
            low, high = max(min(values) - margin, 0.0), max(values) + margin
            found[name] |= {
                "spread_low": min(values),
                "spread_high": max(values),
                "margin": margin,
                "low": low,
                "high": high,
                "inside": bool(low <= real <= high),
            }
    return found


def model_error_margins(scenario: Scenario, plant_file: Path | str | None) -> dict[str, float]:
    """The margins a plant file's ``model_error`` (what the twin missed on its held-out runs,
    :mod:`twin_cosim.model_error`) sets on E_pk (um), ITAE (um.s^2) and IAU (A.s) over the
    scenario's metrics window; none without a file or the section.

    The window [t_0, t_F] holds N samples of the position loop, and the metrics' rectangle
    sums span N periods (:mod:`twin_cosim.metrics`): the bounds take T = t_F - t_0 plus one
    period."""
    if plant_file is None:
        return {}
    error = read_plant_parameters(plant_file, scenario.model_name()).model_error
    if error is None:
        return {}
    start, end = scenario.metrics_window
    duration = scenario.reference.duration if end is None else end
    return error.margins(duration - start + scenario.settings.position_period)


def plant_samples(scenario: Scenario, plant_file: Path | str | None) -> list[dict[str, float]]:
    """Plant samples within the intervals of a plant parameter file (what its diagnosis leaves
    uncertain): :data:`PREDICTION_SAMPLES` draws as a robust campaign draws them (relative
    factors, :class:`~twin_cosim.optimize.config.UncertaintySet`), as FMU parameters on top of
    the scenario's; none without a file or intervals."""
    if plant_file is None:
        return []
    model = scenario.model_name()
    intervals = read_plant_parameters(plant_file, model).intervals
    nominal = {**plant_model(model).start_values(), **scenario.plant_parameters}
    ranges = relative_ranges(intervals, nominal)
    if not ranges:
        return []
    draws = UncertaintySet(0.0, PREDICTION_SAMPLES + 1, 0, tuple(ranges), ranges).factors()[1:]
    return [{name: nominal[name] * f for name, f in draw.items()} for draw in draws]


def sample_metrics(
    scenario: Scenario, tuned: TunedParameters, samples: list[dict[str, float]]
) -> list[Metrics]:
    """The twin's metrics of ``tuned`` on each plant sample (FMU parameters on top of the
    scenario's), over the scenario's window."""
    if not samples:
        return []
    with Plant(scenario.plant_fmu()) as plant:
        return [
            compute_metrics(
                run_scenario(plant, scenario, tuned, plant_overrides=sample),
                scenario.metrics_window,
            )
            for sample in samples
        ]


def describe(source: str, kind: str, figures: dict[str, dict[str, Any]]) -> str:
    """One line per judged metric: machine, twin prediction, relative error, and the
    prediction's interval (its parts: the plant's intervals, the twin's held-out error) with
    whether the machine's value lies in it."""
    units = {"E_pk_um": "um", "ITAE": "um.s^2", "IAU": "A.s"}
    lines = [f"on the {kind} {source}:"]
    for name, f in figures.items():
        unit = units[name]
        line = (
            f"  {name.removesuffix('_um')}: machine {f['machine']:.4g} {unit}, twin "
            f"predicted {f['twin']:.4g} ({f['relative_error_pct']:+.1f} %)"
        )
        if "low" in f:
            parts = []
            if f["spread_high"] > f["spread_low"]:
                parts.append(f"the plant's intervals {f['spread_low']:.4g}-{f['spread_high']:.4g}")
            if f["margin"] > 0.0:
                parts.append(f"+/- {f['margin']:.3g} {unit} of the twin's held-out error")
            detail = f" ({'; '.join(parts)})" if parts else ""
            line += (
                f", interval {f['low']:.4g}-{f['high']:.4g} {unit}{detail}: "
                f"the machine {'inside' if f['inside'] else 'outside'}"
            )
        lines.append(line)
    return "\n".join(lines)
