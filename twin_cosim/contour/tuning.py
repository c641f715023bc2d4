"""Tuning for contours: a machine's tuning problem, every axis' parameters on circles or a part
program, run by the campaign driver (:mod:`twin_cosim.optimize.driver`).

A candidate is every axis' six parameters, [X.Kp_pos, ..., X.f_H, Y.Kp_pos, ..., Y.f_H]. Its
cases are circles (a grid of radii x feeds x directions) or a part program; on each case the
machine runs in lockstep and the case's value (um) is

- ``G``: the circular deviation (ISO 230-4) of a circle;
- ``spike``: the largest reversal spike |height| of a circle;
- ``contour``: the largest contour error of the run (circle or program).

The fitness is the worst case's value, each optionally relative (``relative: true``: times the
first case's reference value over this case's, the reference being the scenario's own sets,
Fine-Tune by default), plus the penalty when an axis' IAU exceeds the cap times its IAU in the
reference run of that case (a cap per axis), twice the penalty when a run fails or leaves the
error band. A task's cutoff stops a candidate after the first case above it (exact for the
worst case; CE's elite cutoff, :mod:`twin_cosim.optimize.early_stop`).

The machine scenario's ``optimize`` section::

    optimize:
      target: G                   # G | spike | contour
      relative: true              # score each case against the reference sets on it
      circles: {radii_mm: [5, 10, 25], feeds_mm_min: [500, 1000, 2000], directions: [ccw]}
      bounds: {Kp_pos: [20, 150], ...}    # per parameter, for every axis (the single-axis
      iau_cap: 1.05                       # defaults of twin_cosim.optimize.config)
      abort_error_um: 1000
      penalty_um: 1.0e6
      methods: {ce: {...}}

A campaign's folder (:mod:`twin_cosim.optimize.store`) holds ``campaign.json`` (spec, bounds,
fingerprints of the machine file, the program, the start sets and the FMUs, each case's
reference values), ``evaluations.jsonl``, ``progress.json`` and ``result.json`` (``best_params``
with ``axes``: ``twin circle --params result.json`` takes it).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin_cosim.contour.circle import MM_PER_MIN, CircleSpec, run_circle
from twin_cosim.contour.gcode import Program, read_program
from twin_cosim.contour.machine_run import (
    MachinePlants,
    MachineRecord,
    contour_metrics,
    plan_on,
    run_machine,
)
from twin_cosim.controller import TUNED_NAMES, TunedParameters
from twin_cosim.cosim import RunAborted
from twin_cosim.metrics import compute_metrics
from twin_cosim.optimize.algorithms import method_settings
from twin_cosim.optimize.config import DEFAULT_BOUNDS, OptimizeConfig
from twin_cosim.optimize.early_stop import (
    CaseOrder,
    EvaluationTask,
    OwnEvaluations,
    least_fitness,
    lower_bound_above,
)
from twin_cosim.optimize.evaluators import evaluation_result
from twin_cosim.optimize.store import (
    CampaignError,
    check_same_inputs,
    fmu_fingerprint,
    load_spec,
    settings_fingerprint,
)
from twin_cosim.plant import PlantError
from twin_cosim.scenario import load_axes_parameters, load_machine
from twin_cosim.scenario.machine import MachineScenario
from twin_cosim.schema import Checker
from twin_cosim.workers import prepare_worker

TARGETS = ("G", "spike", "contour")
KEYS = {"target", "relative", "circles", "bounds", "iau_cap", "abort_error_um", "penalty_um"}
KEYS |= {"methods"}
GRID_DEFAULT = {"radii_mm": [10.0], "feeds_mm_min": [1000.0], "directions": ["ccw"]}


@dataclass(frozen=True)
class ContourCampaignSpec:
    """What a machine's campaign optimizes and how (stored in ``campaign.json``).

    Attributes
    ----------
    scenario : str
        Machine scenario file (``axes:``; its ``optimize`` section sets the target, the circles
        and the bounds).
    method : str
        Optimizer name.
    seed : int
        Its seed.
    budget : int or None
        Most evaluations; the method's default when None.
    program : str or None
        Part program to tune on instead of the circles.
    target : str or None
        ``G``, ``spike`` or ``contour``; the scenario's when None.
    early_stop : bool
        Stop candidates early where that is exact.
    start : str or None
        Sets the search starts from (a Table 3 set or a file, as ``--params``: one set or one
        per axis); the scenario's own when None. The reference of the relative scores and of
        the IAU caps stays the scenario's own sets.
    """

    scenario: str
    method: str
    seed: int = 0
    budget: int | None = None
    program: str | None = None
    target: str | None = None
    early_stop: bool = True
    start: str | None = None


@dataclass(frozen=True)
class ContourSettings:
    """The checked ``optimize`` section of a machine scenario.

    Attributes
    ----------
    target : str
        What a case's value is: ``G`` (circular deviation), ``spike`` (the largest reversal
        spike) or ``contour`` (the largest contour error), um.
    relative : bool
        Score each case against the reference sets' value on it.
    circles : tuple of CircleSpec
        The grid of circles (radius m, feed m/s, direction).
    config : OptimizeConfig
        Bounds of every axis' parameters (named ``X.Kp_pos``, ...), IAU cap, error band,
        penalty and method settings.
    """

    target: str
    relative: bool
    circles: tuple[CircleSpec, ...]
    config: OptimizeConfig


def contour_settings(machine: MachineScenario, target: str | None = None) -> ContourSettings:
    """Check the machine's ``optimize`` section; ``target`` (command line) wins over its own.

    Raises
    ------
    ScenarioError
        Naming the file and the key.
    """
    check = Checker(machine.source)
    data = check.mapping(machine.optimize, "optimize", KEYS)
    chosen = target or data.get("target", "G")
    if chosen not in TARGETS:
        raise check.fail("optimize.target", f"one of {list(TARGETS)}", chosen)
    relative = data.get("relative", True)
    if not isinstance(relative, bool):
        raise check.fail("optimize.relative", "true or false", relative)
    grid = {
        **GRID_DEFAULT,
        **check.mapping(data.get("circles"), "optimize.circles", set(GRID_DEFAULT)),
    }
    for key in ("radii_mm", "feeds_mm_min"):
        if not isinstance(grid[key], list) or not grid[key]:
            raise check.fail(f"optimize.circles.{key}", "a non-empty list of numbers", grid[key])
    radii = [check.number(r, "optimize.circles.radii_mm", positive=True) for r in grid["radii_mm"]]
    feeds = [
        check.number(f, "optimize.circles.feeds_mm_min", positive=True)
        for f in grid["feeds_mm_min"]
    ]
    directions = check.names(grid["directions"], "optimize.circles.directions")
    if not directions or not set(directions) <= {"cw", "ccw"}:
        raise check.fail("optimize.circles.directions", "a list of cw, ccw", directions)
    circles = tuple(
        CircleSpec(r * 1e-3, f * MM_PER_MIN, d) for r in radii for f in feeds for d in directions
    )
    return ContourSettings(chosen, relative, circles, _config(check, data, machine))


def _config(check: Checker, data: dict[str, Any], machine: MachineScenario) -> OptimizeConfig:
    """Bounds of every axis' six parameters and the campaign's limits."""
    bounds = dict(DEFAULT_BOUNDS)
    for name, pair in check.mapping(
        data.get("bounds"), "optimize.bounds", set(TUNED_NAMES)
    ).items():
        if not (isinstance(pair, list) and len(pair) == 2):
            raise check.fail(f"optimize.bounds.{name}", "[low, high]", pair)
        low = check.number(pair[0], f"optimize.bounds.{name}[0]", minimum=0.0)
        high = check.number(pair[1], f"optimize.bounds.{name}[1]")
        if not low < high or (name in ("Kp_pos", "Kp_vel", "PP3") and low <= 0):
            raise check.fail(f"optimize.bounds.{name}", "0 <= low < high (low > 0 for gains)", pair)
        bounds[name] = (low, high)
    names = tuple(f"{a}.{n}" for a in machine.axis_names for n in TUNED_NAMES)
    iau_cap = data.get("iau_cap", 1.05)
    return OptimizeConfig(
        lower=np.array([bounds[n.split(".")[1]][0] for n in names]),
        upper=np.array([bounds[n.split(".")[1]][1] for n in names]),
        window=(0.0, None),
        iau_cap=None
        if iau_cap is None
        else check.number(iau_cap, "optimize.iau_cap", positive=True),
        abort_error_um=check.number(
            data.get("abort_error_um", 1000.0), "optimize.abort_error_um", positive=True
        ),
        penalty_um=check.number(
            data.get("penalty_um", 1.0e6), "optimize.penalty_um", positive=True
        ),
        methods=check.mapping(data.get("methods"), "optimize.methods"),
        tuned_names=names,
    )


def axes_tuned(machine: MachineScenario, x: np.ndarray) -> dict[str, TunedParameters]:
    """Each axis' parameters from a candidate (ValueError on a set the controller refuses)."""
    n = len(TUNED_NAMES)
    return {
        name: TunedParameters.from_array(x[k * n : (k + 1) * n])
        for k, name in enumerate(machine.axis_names)
    }


def machine_vector(machine: MachineScenario) -> np.ndarray:
    """The machine's own sets as a candidate."""
    return np.concatenate([axis.tuned.as_array() for axis in machine.axes])


@dataclass(frozen=True)
class Case:
    """One run of a candidate: a circle, or a part program (``label`` names it)."""

    label: str
    circle: CircleSpec | None = None
    program: Program | None = None


def cases_of(settings: ContourSettings, program: Program | None) -> tuple[Case, ...]:
    """The program as the only case, else the circles of the grid."""
    if program is not None:
        return (Case(Path(program.source).name, program=program),)
    return tuple(
        Case(f"R{c.radius * 1e3:g}mm-F{c.feed / MM_PER_MIN:g}-{c.direction}", circle=c)
        for c in settings.circles
    )


def run_case(
    machine: MachineScenario, plants: MachinePlants, case: Case, abort_error: float
) -> tuple[MachineRecord, dict[str, float]]:
    """Run one case: its record, and for a circle its G and largest spike |height| (um).

    ``abort_error`` (m): stop once an axis' |x_ref - x| exceeds it
    (:class:`~twin_cosim.cosim.RunAborted`).
    """
    if case.circle is not None:
        run = run_circle(machine, plants, case.circle, abort_error=abort_error)
        spike = max(abs(s.height_um) for s in run.result.spikes)
        return run.record, {"G": run.result.G_um, "spike": spike}
    motion = plan_on(machine, case.program)  # from the machine's origin, every axis at 0 m
    return run_machine(machine, motion, plants, abort_error=abort_error), {}


def case_values(
    machine: MachineScenario, plants: MachinePlants, case: Case, abort_error: float
) -> dict[str, Any]:
    """Run one case: its G, largest spike and contour error (um), each axis' IAU (A.s) and the
    speed-loop steps simulated (all axes)."""
    record, values = run_case(machine, plants, case, abort_error)
    values["contour"] = contour_metrics(record)["contour_error_max_um"]
    values["IAU"] = {name: compute_metrics(frame).IAU for name, frame in record.axes.items()}
    ratio = machine.axes[0].settings.speed_steps_per_position_step
    values["steps"] = sum(len(f) for f in record.axes.values()) * ratio
    return values


# What a machine's campaign.json holds besides its spec (and the type of each)
RECORD_KEYS: Mapping[str, type] = {
    "target": str,
    "relative": bool,
    "cases": list,
    "references": list,
}


def load_contour_spec(out_dir: Path) -> ContourCampaignSpec:
    """The spec of the machine's campaign stored in ``out_dir`` (for ``--resume``)."""
    return load_spec(out_dir, ContourCampaignSpec, RECORD_KEYS)


def prepare_machine_worker() -> None:
    """What a pool's process of a machine's campaign runs as it starts: the compiled loops
    loaded, the machine's objective imported."""
    prepare_worker((__name__,))


@dataclass(frozen=True)
class MachineProblem:
    """A machine's campaign as the driver runs it (:class:`~twin_cosim.optimize.driver.Problem`).

    Attributes
    ----------
    spec : ContourCampaignSpec
        What was asked (``campaign.json``'s ``spec``): method, seed, budget, program, target.
    machine : MachineScenario
        The machine, its own sets the reference.
    settings : ContourSettings
        Its ``optimize`` section, the target given on top.
    runs : tuple of Case
        The cases every candidate runs: the circles, or the part program.
    """

    spec: ContourCampaignSpec
    machine: MachineScenario
    settings: ContourSettings
    runs: tuple[Case, ...]

    record_keys = RECORD_KEYS
    prepare_worker = staticmethod(prepare_machine_worker)

    @classmethod
    def load(cls, spec: ContourCampaignSpec) -> MachineProblem:
        """The problem of ``spec``: its machine, ``optimize`` section and program read now.

        Raises
        ------
        CampaignError, ScenarioError
            On a program with a target other than ``contour``, or a bad file.
        """
        machine = load_machine(spec.scenario)
        settings = contour_settings(machine, spec.target)
        if spec.program and settings.target != "contour":
            raise CampaignError(f"target {settings.target}: a part program is tuned on 'contour'")
        program = read_program(spec.program, machine.axis_names) if spec.program else None
        return cls(spec, machine, settings, cases_of(settings, program))

    @property
    def config(self) -> OptimizeConfig:
        """Bounds of every axis' parameters, the limits and the method settings."""
        return self.settings.config

    @property
    def case_count(self) -> int:
        """The runs of every candidate."""
        return len(self.runs)

    def start(self) -> np.ndarray:
        """The sets the search starts from (``spec.start``; else the machine's own) as a
        candidate."""
        first = self.machine
        if self.spec.start:
            first = first.with_tuned(load_axes_parameters(self.spec.start, first.axis_names))
        return machine_vector(first)

    def method_settings(self) -> dict[str, Any]:
        """The method's settings: the scenario's, and the spec's budget."""
        spec = self.spec
        configured = self.config.methods.get(spec.method, {})
        return method_settings(spec.method, spec.start, configured, {}, spec.budget)

    def fingerprints(self, settings: dict[str, Any]) -> dict[str, Any]:
        """Content fingerprints of the machine file, the program, the start sets' file, each
        axis' FMU, and the spec with the method settings."""
        spec = self.spec
        program = b"" if spec.program is None else Path(spec.program).read_bytes()
        start = (
            b""
            if spec.start is None or not Path(spec.start).is_file()
            else Path(spec.start).read_bytes()
        )
        return {
            "scenario": hashlib.sha256(Path(self.machine.source).read_bytes()).hexdigest(),
            "program": hashlib.sha256(program).hexdigest(),
            "start": hashlib.sha256(start).hexdigest(),
            "plant_fmus": {a.name: fmu_fingerprint(a.plant_fmu()) for a in self.machine.axes},
            "settings": settings_fingerprint({"spec": asdict(spec), "settings": settings}),
        }

    def check_stored(self, out_dir: Path, record: dict[str, Any], found: dict[str, Any]) -> None:
        """Refuse a resume whose machine file, program, start sets, FMUs or settings differ
        from the stored campaign's."""
        spec = self.spec
        names = {
            "scenario": f"machine scenario {spec.scenario}",
            "program": f"part program {spec.program}",
            "start": f"start sets {spec.start}",
            "plant_fmus": "plant FMUs",
            "settings": "optimizer settings",
        }
        check_same_inputs(out_dir, record, found, names)

    def objective(self, record: dict[str, Any] | None) -> ContourObjectiveSpec:
        """What the workers build their objective from; ``record``: the campaign's record (each
        case's reference values), None for the reference runs."""
        references = () if record is None else tuple(record["references"])
        return ContourObjectiveSpec(self.machine, self.settings, self.runs, references)

    def new_record(self, references: list[dict[str, Any]], found: dict[str, Any]) -> dict:
        """The record of a new campaign: each case's reference values (the machine's own sets)
        and the fingerprints."""
        for reference in references:
            reference.pop("steps")
        settings = self.settings
        return {
            "spec": asdict(self.spec),
            "config": settings.config.as_dict(),
            "target": settings.target,
            "relative": settings.relative,
            "cases": [c.label for c in self.runs],
            "references": references,
            "reference_params": {a.name: a.tuned.as_dict() for a in self.machine.axes},
            "fingerprints": found,
        }

    def cutoff_is_exact(self) -> bool:
        """Always: the worst case over the cases is above a cutoff once one case is."""
        return True

    def best(self, x: np.ndarray, record: dict[str, Any]) -> dict[str, Any]:
        """The best candidate's sets per axis (``best_params.axes``), the reference values, the
        reference sets' fitness (um: the first case's value when relative, else the largest),
        the cases and the target."""
        values = [r[record["target"]] for r in record["references"]]
        axes = {name: t.as_dict() for name, t in axes_tuned(self.machine, x).items()}
        return {
            "best_params": {"axes": axes},
            "reference": record["references"],
            "details": {
                "reference_fitness": values[0] if record["relative"] else max(values),
                "relative": record["relative"],
                "cases": record["cases"],
                "target": self.settings.target,
            },
        }


@dataclass(frozen=True)
class ContourObjectiveSpec:
    """What a worker builds the objective from (picklable: resolved values only).

    Attributes
    ----------
    machine : MachineScenario
        The machine: every axis' plant, controller and limits (its own sets the reference).
    settings : ContourSettings
        Target, circles and limits.
    cases : tuple of Case
        The runs of every candidate.
    references : tuple of dict
        Per case: the reference sets' values (``G``, ``spike``, ``contour`` um, ``IAU`` A.s
        per axis), for the IAU caps and the relative scales; empty for the reference runs.
    """

    machine: MachineScenario
    settings: ContourSettings
    cases: tuple[Case, ...]
    references: tuple[dict[str, Any], ...] = ()

    def build(self) -> ContourObjective:
        """The objective (a worker of :mod:`twin_cosim.workers`)."""
        return ContourObjective(self)


class ContourObjective:
    """Scores candidates on one set of plant instances (one per axis, reset per run)."""

    def __init__(self, spec: ContourObjectiveSpec) -> None:
        self.spec = spec
        self.plants = MachinePlants(spec.machine)
        self._order = CaseOrder(len(spec.cases))
        self._own = OwnEvaluations()

    def reference_of(self, index: int) -> dict[str, Any]:
        """Case ``index``'s values with the machine's own sets (the reference):
        :func:`case_values`."""
        return case_values(self.spec.machine, self.plants, self.spec.cases[index], math.inf)

    def record(self, x: np.ndarray | None, index: int = 0) -> MachineRecord:
        """The record of case ``index`` run with candidate ``x`` (every axis' parameters; None:
        the machine's own sets), for figures.

        Raises
        ------
        ValueError
            When the controller refuses the candidate's values.
        """
        machine = self.spec.machine
        if x is not None:
            machine = machine.with_tuned(axes_tuned(machine, np.asarray(x)))
        return run_case(machine, self.plants, self.spec.cases[index], math.inf)[0]

    def __call__(self, task: EvaluationTask | np.ndarray) -> dict[str, Any]:
        """Evaluate one candidate (an EvaluationTask, its cutoff lowered by this worker's own
        complete evaluations of its generation, or a vector of every axis' parameters).

        Returns
        -------
        dict
            ``fitness`` (um; relative scores in the first case's units), ``status`` (ok,
            violation, unstable, failed, stopped), ``reason``, ``metrics`` (the target's largest
            value over the cases and its case, e.g. ``G`` and ``G_case``; the worst case, the one
            that sets the fitness, and its own value, ``worst_case`` and ``worst_case_G``; per
            case the values) and ``steps`` (speed-loop steps simulated, all axes).
        """
        return self._own.evaluate(task, self.evaluate)

    def evaluate(self, x: np.ndarray, cutoff: float) -> dict[str, Any]:
        """The result of :meth:`__call__` for ``x`` with cutoff ``cutoff`` (um)."""
        settings = self.spec.settings
        config = settings.config
        failure = 2.0 * config.penalty_um
        try:
            machine = self.spec.machine.with_tuned(axes_tuned(self.spec.machine, np.asarray(x)))
        except ValueError as exc:
            return evaluation_result(failure, "failed", str(exc), None, 0)
        scores: dict[int, float] = {}
        runs: dict[int, dict[str, Any]] = {}
        steps = 0
        count = len(self.spec.cases)
        for i in self._order:
            case = self.spec.cases[i]
            try:
                values = case_values(machine, self.plants, case, config.abort_error_um * 1e-6)
            except RunAborted as exc:
                return evaluation_result(failure, "unstable", f"{case.label}: {exc}", None, steps)
            except PlantError as exc:
                return evaluation_result(failure, "failed", f"{case.label}: {exc}", None, steps)
            steps += values.pop("steps")
            scores[i], status, reason = self._score(i, values)
            runs[i] = {"case": case.label, "status": status, "reason": reason, **values}
            worst = least_fitness(scores.values(), count, "worst")
            if worst > cutoff and len(scores) < count:
                self._order.first(i)
                reason = f"{case.label}: fitness at least {worst:.6g} um, above the cutoff"
                return evaluation_result(lower_bound_above(cutoff), "stopped", reason, None, steps)
        ordered = [runs[i] for i in range(len(runs))]
        worst_case = max(range(len(ordered)), key=lambda i: scores[i])
        self._order.first(worst_case)
        status = "ok" if all(r["status"] == "ok" for r in ordered) else "violation"
        reason = "; ".join(r["reason"] for r in ordered if r["reason"])
        target = settings.target
        largest = max(range(len(ordered)), key=lambda i: ordered[i][target])
        metrics = {
            target: ordered[largest][target],
            f"{target}_case": ordered[largest]["case"],
            "worst_case": ordered[worst_case]["case"],
            f"worst_case_{target}": ordered[worst_case][target],
            "runs": ordered,
        }
        return evaluation_result(scores[worst_case], status, reason, metrics, steps)

    def _score(self, i: int, values: dict[str, Any]) -> tuple[float, str, str]:
        """Fitness (um), status and reason of case ``i``'s values."""
        settings = self.spec.settings
        reference = self.spec.references[i]
        scale = 1.0
        if settings.relative:
            scale = self.spec.references[0][settings.target] / reference[settings.target]
        score = scale * values[settings.target]
        cap = settings.config.iau_cap
        if cap is not None:
            over = [
                f"axis {name}: IAU {iau:.4g} A.s above the cap {cap * reference['IAU'][name]:.4g}"
                for name, iau in values["IAU"].items()
                if iau > cap * reference["IAU"][name]
            ]
            if over:
                return settings.config.penalty_um + score, "violation", "; ".join(over)
        return score, "ok", ""

    def close(self) -> None:
        """Free the plants."""
        self.plants.close()
