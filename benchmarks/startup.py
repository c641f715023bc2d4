"""Where the start-up of twin's commands goes, and each command's wall beside the pure stepping
of the same work, measured in one run.

    python benchmarks/startup.py [--repeat N] [--workers N] [--compare-budget N] [--quick]

Four parts, each in fresh interpreters (``python -m twin_cosim`` as a user runs it; warm: the
FMU and the loops built (``twin build``), the extracted FMU in place, the project's bytecode
compiled (a first run writes it; compiled here too, for an environment with
``PYTHONDONTWRITEBYTECODE`` set), files in the OS cache):

1. Import time of ``twin simulate reference1`` (``python -X importtime``), self times summed by
   top-level package.
2. The phases of one run in a fresh process: interpreter, imports, the compiled loops readied
   (the library built ahead, else numba's compiler target and cache), FMU extraction (into an
   empty cache) and instantiation, reference
   preparation, stepping, metrics, file writing, plotting (import and drawing).
3. A process pool of ``--workers``: its spawn and each worker's initialisation (imports and
   compiled loop), until every worker has answered a task.
4. The wall (median of ``--repeat``) of ``twin simulate reference1`` with and without its plot,
   a 20-evaluation CE campaign, the paper's CE campaign (``twin optimize reference1 --method ce
   --seed 11``, 440 evaluations), a null ``twin diagnose`` (a run synthesized without effects)
   and ``twin compare`` over the five methods (``--compare-budget`` evaluations each), each
   beside the pure stepping time of the same work: the time inside the compiled loop
   (``master`` of :mod:`twin_cosim.loops`) for every speed-loop step the command
   simulates, spread evenly over its workers, each stepping at the speed measured with as
   many processes stepping at once (slower than one alone where cores share their resources).
   The ratio wall / stepping is the figure: these machines are shared and noisy, so the
   seconds follow the load (printed, with the command line, under the tables).
"""

from __future__ import annotations

import argparse
import compileall
import importlib.util
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TWIN = [sys.executable, "-m", "twin_cosim"]
PACKAGES = ("numpy", "pandas", "scipy", "numba", "llvmlite", "fmpy", "matplotlib", "yaml")


# ---------------------------------------------------------------- children (fresh processes)


def phases() -> dict[str, float]:
    """Times (s) of the phases of one reference-1 run in this (fresh) process."""
    found: dict[str, float] = {}
    mark = [time.perf_counter()]

    def lap(name: str) -> None:
        now = time.perf_counter()
        found[name] = now - mark[0]
        mark[0] = now

    import numpy  # noqa: F401

    lap("import numpy")
    import fmpy.fmi2  # noqa: F401

    lap("import fmpy")
    import twin_cosim.cosim as cosim
    from twin_cosim.scenario import resolve_scenario

    lap("import twin_cosim (scenario, cosim)")
    from twin_cosim.loops.ahead import compiled_loops, ready_compiled_loops

    ready_compiled_loops()
    lap(f"compiled loops ready ({_loops_kind(compiled_loops())})")
    from twin_cosim.plant import Plant, extracted_fmu

    with empty_cache():
        mark[0] = time.perf_counter()
        resolve_scenario("reference1")
        lap("reference preparation, first time (SciPy's spline)")
    mark[0] = time.perf_counter()
    scenario = resolve_scenario("reference1")
    lap("reference preparation, grid cached")
    fmu = scenario.plant_fmu()
    lap("FMU found (build check)")
    with empty_cache():
        mark[0] = time.perf_counter()
        extracted_fmu(fmu)
        lap("FMU extraction, first time")
    mark[0] = time.perf_counter()
    plant = Plant(fmu)
    lap("FMU instantiation (extraction cached)")
    cosim.run_scenario(plant, scenario)
    first = time.perf_counter() - mark[0]
    record = cosim.run_scenario(plant, scenario)
    second = time.perf_counter() - mark[0] - first
    found["first run's extra (first run - second)"] = first - second
    found["stepping (a warm run)"] = second
    mark[0] = time.perf_counter()
    from twin_cosim.metrics import compute_metrics

    metrics = compute_metrics(record, scenario.metrics_window)
    lap("metrics")
    from twin_cosim.commands.console import write_json, write_record_csv

    with tempfile.TemporaryDirectory() as out:
        mark[0] = time.perf_counter()
        write_record_csv(Path(out) / "record.csv", record)
        lap("record.csv")
        from twin_cosim.versions import versions

        write_json(Path(out) / "summary.json", {"metrics": metrics.as_dict(), **versions()})
        lap("summary.json (versions)")
        from twin_cosim.plots import plot_run

        lap("import matplotlib (plots)")
        plot_run(record, metrics, "reference1", Path(out) / "run.png")
        lap("run.png")
    plant.close()
    return found


@contextmanager
def empty_cache() -> Iterator[None]:
    """The per-user cache is an empty folder meanwhile (what a first run finds)."""
    from fmu_build.build import CACHE_ENV

    before = os.environ.get(CACHE_ENV)
    with tempfile.TemporaryDirectory() as empty:
        os.environ[CACHE_ENV] = empty
        try:
            yield
        finally:
            if before is None:
                del os.environ[CACHE_ENV]
            else:
                os.environ[CACHE_ENV] = before


def pool_start(workers: int) -> dict[str, float]:
    """Times (s) until a pool of ``workers`` started now has answered one task per worker."""
    from twin_cosim.workers import ProcessPool, prepare_campaign_worker

    start = time.perf_counter()
    with ProcessPool(None, workers, prepare_campaign_worker) as pool:
        spawned = time.perf_counter() - start
        answered = set()
        while len(answered) < workers:
            answered |= {pid for _, pid in pool.imap([0] * workers, ProcessId())}
        ready = time.perf_counter() - start
    started = time.perf_counter()
    prepare_campaign_worker()
    return {
        f"spawn {workers} processes (returns at once)": spawned,
        f"every worker initialised and answering ({workers} in parallel)": ready,
        "one worker's initialisation, alone (imports, compiled loop)": (
            time.perf_counter() - started
        ),
    }


class ProcessId:
    """A worker factory whose workers answer their process id."""

    def build(self) -> ProcessId:
        return self

    def __call__(self, task: int) -> int:
        return os.getpid()

    def close(self) -> None:
        pass


def cost_per_step() -> float:
    """Seconds per speed-loop step inside the compiled loop (best of a few warm runs)."""
    import twin_cosim.cosim as cosim
    from twin_cosim.plant import Plant
    from twin_cosim.scenario import resolve_scenario

    scenario = resolve_scenario("reference1")
    steps = len(scenario.reference.position) * scenario.settings.speed_steps_per_position_step
    with Plant(scenario.plant_fmu()) as plant:
        cosim.run_scenario(plant, scenario)
        best = min(_loop_time(lambda: cosim.run_scenario(plant, scenario)) for _ in range(5))
    return best / steps


def diagnose_stepping(measured: str) -> float:
    """Seconds inside the compiled loop of the null diagnosis, run serially in this process."""
    from twin_cosim.gap.diagnosis import diagnose
    from twin_cosim.measured import read_measured
    from twin_cosim.scenario import resolve_scenario

    scenario = resolve_scenario("diagnosis")
    run = read_measured(measured)
    return _loop_time(lambda: diagnose(scenario, [run], workers=1))


def _loops_kind(loops: object) -> str:
    """Which compiled loops a process runs: the library built ahead or numba's just in time."""
    return "numba, just in time" if loops.__name__.endswith("kernels") else "library built ahead"


def _loop_time(work) -> float:
    """Seconds spent inside the compiled ``master`` while ``work()`` runs in this process."""
    from types import SimpleNamespace

    from twin_cosim.loops import ahead as loops

    compiled = loops.compiled_loops()
    spent = [0.0]

    def timed(*args):
        start = time.perf_counter()
        try:
            return compiled.master(*args)
        finally:
            spent[0] += time.perf_counter() - start

    loops._LOADED[:] = [SimpleNamespace(master=timed, __name__=compiled.__name__)]
    try:
        work()
    finally:
        loops._LOADED[:] = [compiled]
    return spent[0]


# ---------------------------------------------------------------- the parent


def child(*arguments: str) -> object:
    """Run this script in a fresh interpreter (``--child ...``); its JSON answer."""
    done = subprocess.run(
        [sys.executable, __file__, "--child", *arguments],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout)


def wall(command: list[str], cwd: Path) -> float:
    """Wall time (s) of one run of ``command``; it must succeed."""
    start = time.perf_counter()
    subprocess.run(command, cwd=cwd, check=True, capture_output=True)
    return time.perf_counter() - start


def median_wall(command: list[str], cwd: Path, repeat: int, before=None) -> float:
    """Median wall (s) of ``repeat`` runs; ``before()`` runs untimed before each."""
    times = []
    for _ in range(repeat):
        if before:
            before()
        times.append(wall(command, cwd))
    return statistics.median(times)


def import_times(cwd: Path) -> dict[str, float]:
    """Import self times (s) of ``twin simulate reference1`` summed by top-level package."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", *TWIN[1:], "simulate", "reference1", "--out", "imp"],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=True,
    )
    totals: dict[str, float] = defaultdict(float)
    for line in done.stderr.splitlines():
        match = re.match(r"import time:\s+(\d+) \|\s+\d+ \|\s*(\S+)", line)
        if match:
            package = match.group(2).split(".")[0]
            name = package if package in PACKAGES + ("twin_cosim", "fmu_build") else "other"
            totals[name] += int(match.group(1)) / 1e6
    return dict(sorted(totals.items(), key=lambda item: -item[1]))


def campaign_steps(folder: Path) -> int:
    """Speed-loop steps of a campaign folder's evaluations."""
    lines = (folder / "evaluations.jsonl").read_text().splitlines()
    return sum(json.loads(line)["steps"] for line in lines)


def comparison_file(folder: Path, budget: int) -> Path:
    """A comparison of the five methods on reference 1 (validated on reference 2)."""
    path = folder / "compare.yaml"
    budgets = ", ".join(f"{m}: {budget}" for m in ("ce", "ga", "sa", "cmaes", "de"))
    path.write_text(
        f"name: startup-compare\nscenario: {ROOT}/scenarios/reference1.yaml\n"
        f"validation: {ROOT}/scenarios/reference2.yaml\nmethods: [ce, ga, sa, cmaes, de]\n"
        f"seed: 0\nbudgets: {{{budgets}}}\n"
    )
    return path


def row(name: str, seconds: float, stepping: float, loop: float | None = None) -> str:
    """A line of the walls' table; ``loop``: the seconds in a campaign's evaluation loop."""
    looped = "-" if loop is None else f"{loop:.2f}"
    return f"| {name} | {seconds:.2f} | {looped} | {stepping:.3f} | {seconds / stepping:.1f} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per wall (median)")
    parser.add_argument("--workers", type=int, default=2, help="pool size of the campaigns")
    parser.add_argument(
        "--compare-budget",
        type=int,
        default=40,
        help="evaluations per method of twin compare (0: scenarios/paper_campaign.yaml, each "
        "method's own budget)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="leave out the 440-evaluation campaign and compare"
    )
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        kind, *rest = args.child
        answers = {
            "phases": phases,
            "pool": lambda: pool_start(int(rest[0])),
            "step": cost_per_step,
            "diagnose": lambda: diagnose_stepping(rest[0]),
        }
        print(json.dumps(answers[kind]()))
        return
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as folder:
        report(args, Path(folder))
    print(
        f"\n`python benchmarks/startup.py {' '.join(sys.argv[1:])}`: {platform.node()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}; load average "
        f"{load[0]:.1f} before, {os.getloadavg()[0]:.1f} after."
    )


def report(args: argparse.Namespace, tmp: Path) -> None:
    """Measure and print the four parts."""
    subprocess.run(
        [*TWIN, "simulate", "reference1", "--out", "warm"], cwd=tmp, check=True, capture_output=True
    )  # warm: FMU built, loop cached, FMU extracted
    for package in ("twin_cosim", "fmu_build"):  # warm: the bytecode a first run writes
        spec = importlib.util.find_spec(package)
        compileall.compile_dir(Path(spec.origin).parent, quiet=1)
    print("## Import time of `twin simulate reference1` (self times by package)\n")
    print("| package | s |\n|---|---|")
    for package, seconds in import_times(tmp).items():
        print(f"| {package} | {seconds:.3f} |")
    print("\n## Phases of one run (fresh process)\n")
    print("| phase | s |\n|---|---|")
    for name, seconds in child("phases").items():
        print(f"| {name} | {seconds:.3f} |")
    print(
        f"| interpreter start (`python -c pass`) | "
        f"{median_wall([sys.executable, '-c', 'pass'], tmp, args.repeat):.3f} |"
    )
    print(f"\n## A pool of {args.workers} workers\n")
    print("| phase | s |\n|---|---|")
    for name, seconds in child("pool", str(args.workers)).items():
        print(f"| {name} | {seconds:.3f} |")
    per_step = child("step")
    together = stepping_together(args.workers)
    run_steps = 155_204  # speed-loop steps of one reference-1 run
    walls(args, tmp, (per_step, together), run_steps)


def stepping_together(workers: int) -> float:
    """Seconds per speed-loop step in each of ``workers`` processes stepping at once (the median
    of theirs): what a pool's worker steps at while the others step too."""
    command = [sys.executable, __file__, "--child", "step"]
    running = [subprocess.Popen(command, stdout=subprocess.PIPE, text=True) for _ in range(workers)]
    answers = [json.loads(process.communicate()[0]) for process in running]
    if any(process.returncode for process in running):
        raise RuntimeError("a stepping process failed")
    return statistics.median(answers)


def walls(
    args: argparse.Namespace, tmp: Path, per_step: tuple[float, float], run_steps: int
) -> None:
    """Part 4: each command's wall beside the pure stepping of its work (``per_step``: seconds
    per speed-loop step alone, and in each of ``args.workers`` processes stepping at once)."""
    w = args.workers
    alone, together = per_step
    one_run = run_steps * alone
    print(
        f"\n## Walls (median of {args.repeat}) beside pure stepping "
        f"({alone * 1e6:.3f} us per step alone, {together * 1e6:.3f} us in each of {w} "
        f"processes stepping at once; a command of {w} workers is set beside the latter)\n"
    )
    print(
        "| command | wall [s] | in the loop [s] | stepping [s] | wall / stepping |\n"
        "|---|---|---|---|---|"
    )
    simulate = [*TWIN, "simulate", "reference1", "--out", "sim"]
    print(row("`twin simulate reference1`", median_wall(simulate, tmp, args.repeat), one_run))
    print(
        row(
            "`twin simulate reference1 --no-plots`",
            median_wall([*simulate, "--no-plots"], tmp, args.repeat),
            one_run,
        )
    )
    campaigns = [(20, ["--budget", "20"])]
    if not args.quick:
        campaigns.append((440, []))
    for evaluations, extra in campaigns:
        out = tmp / f"ce{evaluations}"
        command = [
            *TWIN,
            "optimize",
            "reference1",
            "--method",
            "ce",
            "--seed",
            "11",
            "--workers",
            str(w),
            "--quiet",
            "--out",
            str(out),
            *extra,
        ]
        seconds = median_wall(
            command,
            tmp,
            args.repeat,
            before=lambda out=out: subprocess.run(["rm", "-rf", str(out)]),
        )
        steps = campaign_steps(out) + 3 * run_steps  # evaluations, reference, best_run.png
        loop = json.loads((out / "result.json").read_text())["wall_s"]
        print(
            row(
                f"`twin optimize reference1 --method ce --seed 11 --workers {w}"
                f"{' --budget 20' if extra else ''}` ({evaluations} evaluations)",
                seconds,
                steps * together / w,
                loop,
            )
        )
    subprocess.run(
        [*TWIN, "synth", "diagnosis", "--out", "null.csv", "--force"],
        cwd=tmp,
        check=True,
        capture_output=True,
    )
    diagnose = [
        *TWIN,
        "diagnose",
        "diagnosis",
        "--measured",
        "null.csv",
        "--workers",
        str(w),
        "--quiet",
        "--out",
        "diag",
    ]
    stepping = child("diagnose", str(tmp / "null.csv"))
    print(
        row(
            f"`twin diagnose diagnosis --measured null.csv --workers {w}` (null run)",
            median_wall(diagnose, tmp, args.repeat),
            stepping * together / alone / w,
        )
    )
    if not args.quick:
        compare(args, tmp, together, run_steps)


def compare(args: argparse.Namespace, tmp: Path, per_step: float, run_steps: int) -> None:
    """``twin compare`` over the five methods: its wall, the share in campaign loops, stepping
    (``per_step``: seconds per speed-loop step of a worker while the others step too)."""
    w = args.workers
    path = (
        comparison_file(tmp, args.compare_budget)
        if args.compare_budget
        else ROOT / "scenarios" / "paper_campaign.yaml"
    )
    out = tmp / "compare"
    command = [*TWIN, "compare", str(path), "--workers", str(w), "--quiet", "--out", str(out)]
    subprocess.run(["rm", "-rf", str(out)])
    seconds = wall(command, tmp)
    tables = json.loads((out / "tables.json").read_text())
    loops = sum(c["wall_s"] for c in tables["campaigns"].values())
    steps = sum(campaign_steps(out / m) for m in tables["campaigns"])
    steps += (5 + 6 * 2) * run_steps  # reference runs, Table 4 and 5 runs (6 sets x 2)
    stepping = steps * per_step / w
    budget = f"{args.compare_budget} evaluations each" if args.compare_budget else "paper budgets"
    print(row(f"`twin compare` five methods, {budget}", seconds, stepping, loops))
    print(
        f"\n`twin compare`: {loops / seconds:.0%} of its wall in the campaigns' evaluation "
        f"loops, {stepping / seconds:.0%} pure stepping."
    )


if __name__ == "__main__":
    main()
