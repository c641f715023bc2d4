"""A benchmark of two trees, paired in one run: this checkout against a base revision.

The base revision is checked out into a temporary git worktree; both trees run with this
checkout's virtual environment, each importing its own package (``PYTHONPATH=<tree>``), each on
its own loops compiled ahead (``python -m twin_cosim build`` in each tree first, so that neither
side compiles just in time). The benchmark script (a path inside the trees, each tree running
its own copy) runs ``--rounds`` times per tree, the two trees in turn (the first alternating, so
that neither always runs first on a machine whose load drifts); every run prints its figures as
one JSON object on its last line (the scripts' ``--json``). Printed: each figure's median per
tree and the ratio this tree / base of the medians; the least per tree and the ratio of the
least; the median of the rounds' own ratios (each round's two runs ran one after the other, under
much the same load); and the load average before and after.

    python benchmarks/paired.py --base REV [--rounds N] -- benchmarks/step_speed.py --json ...
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def tree_environment(tree: Path) -> dict[str, str]:
    """The environment of a run of ``tree``: its package first on the path."""
    return {**os.environ, "PYTHONPATH": str(tree)}


def check_imports_from(tree: Path) -> None:
    """Fail unless the package imported with ``tree``'s environment is ``tree``'s own."""
    found = subprocess.run(
        [sys.executable, "-c", "import twin_cosim; print(twin_cosim.__file__)"],
        env=tree_environment(tree),
        cwd=tree,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    if not Path(found).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"{tree}: imports twin_cosim from {found}, not from the tree")


def build(tree: Path) -> None:
    """Build the tree's FMUs and its loops ahead (``twin build``)."""
    subprocess.run(
        [sys.executable, "-m", "twin_cosim", "build"],
        env=tree_environment(tree),
        cwd=tree,
        check=True,
        stdout=subprocess.DEVNULL,
    )


def run_once(tree: Path, script: list[str]) -> dict[str, float]:
    """The figures of one run of the tree's own copy of the script."""
    done = subprocess.run(
        [sys.executable, str(tree / script[0]), *script[1:]],
        env=tree_environment(tree),
        cwd=tree,
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        raise SystemExit(f"{tree}: {' '.join(script)} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def paired(trees: dict[str, Path], script: list[str], rounds: int) -> dict[str, list[dict]]:
    """Every tree's figures of ``rounds`` runs, the trees in turn."""
    found: dict[str, list[dict]] = {name: [] for name in trees}
    names = list(trees)
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            found[name].append(run_once(trees[name], script))
            print(f"round {r + 1}/{rounds} {name}: {found[name][-1]}", file=sys.stderr)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", required=True, help="the base revision (a git revision)")
    parser.add_argument("--rounds", type=int, default=7, help="runs per tree")
    parser.add_argument(
        "script", nargs="+", help="the benchmark (path in the tree) and its options"
    )
    args = parser.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="paired-") as folder:
        base = Path(folder) / "base"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(base), args.base],
            check=True,
            capture_output=True,
        )
        try:
            trees = {"base": base, "this": ROOT}
            for tree in trees.values():
                check_imports_from(tree)
                build(tree)
            found = paired(trees, args.script, args.rounds)
        finally:
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(base)], check=True
            )
    load_after = os.getloadavg()
    revision = subprocess.run(
        ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    print(f"{' '.join(args.script)}: {args.rounds} runs per tree, this = {revision} (and any")
    print(f"changes not committed), base = {args.base}")
    print(f"{'figure':<34}{'statistic':<16}{'base':>13}{'this':>13}{'this / base':>13}")
    for figure in found["base"][0]:
        base = [run[figure] for run in found["base"]]
        this = [run[figure] for run in found["this"]]
        for statistic, pick in (("median", statistics.median), ("least", min)):
            b, t = pick(base), pick(this)
            print(f"{figure:<34}{statistic:<16}{b:>13.6g}{t:>13.6g}{t / b:>13.4f}")
        rounds = statistics.median(t / b for t, b in zip(this, base, strict=True))
        label = "rounds' ratios"
        print(f"{figure:<34}{label:<16}{'':>26}{rounds:>13.4f} (median)")
    print(
        "load average (1, 5, 15 min): before "
        + ", ".join(f"{v:.2f}" for v in load_before)
        + "; after "
        + ", ".join(f"{v:.2f}" for v in load_after)
    )


if __name__ == "__main__":
    main()
