"""Start-up time of ``twin --help``: the lazy command line against eager imports, in one run.

    python benchmarks/cli_startup.py [--repeat N]

Three fresh interpreters, each timed N times (best and median wall time):

- ``python``: an interpreter that imports nothing of ours (the floor);
- ``lazy``: ``twin --help`` as it is (the command line imports the standard library and the
  light registries only);
- ``eager``: ``twin --help`` after importing exactly what the command line imported at start
  before it became lazy (fmu_build.build, twin_cosim.plant, .metrics, .reference, .scenario:
  fmpy, numpy, pandas, scipy, yaml); the commands' numba and matplotlib are not counted.

The figure that matters is the ratio eager / lazy, measured on the same machine in the same run.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

EAGER_IMPORTS = (
    "import fmpy, fmu_build.build, twin_cosim.plant, twin_cosim.metrics, twin_cosim.reference, "
    "twin_cosim.scenario"
)
CASES = {
    "python": ["-c", "pass"],
    "lazy": ["-m", "twin_cosim", "--help"],
    "eager": ["-c", f"{EAGER_IMPORTS}; from twin_cosim.cli import main; main(['--help'])"],
}


def wall_times(arguments: list[str], repeat: int) -> list[float]:
    """Wall times (s) of ``repeat`` runs of a fresh interpreter with ``arguments``."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([sys.executable, *arguments], check=False, capture_output=True)
        times.append(time.perf_counter() - start)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="runs per case (default: 7)")
    args = parser.parse_args()
    results = {name: wall_times(arguments, args.repeat) for name, arguments in CASES.items()}
    print("| case | best [s] | median [s] |")
    print("|---|---|---|")
    for name, times in results.items():
        print(f"| {name} | {min(times):.3f} | {statistics.median(times):.3f} |")
    ratio = min(results["eager"]) / min(results["lazy"])
    print(f"\neager / lazy (best of {args.repeat}): {ratio:.1f}x")


if __name__ == "__main__":
    main()
