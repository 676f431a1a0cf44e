"""Run time of every grader check on its reference solution, here and (optionally) at an earlier commit.

    python benchmarks/check_times.py                 # this checkout
    python benchmarks/check_times.py 8df1575         # this checkout against that commit

Each solution notebook's code cells (grader cells skipped) run once in a fresh process of the
tree being measured; then each grader check is called on the solution's object ``--repeats``
times and the median is reported in milliseconds. With a commit, its tree is checked out into a
temporary ``git worktree`` and measured in alternating processes with this one, and the table
shows both medians and their ratio (the stable number on a shared machine).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from worktree import ROOT, checked_out

# Runs in a child process with the tree to measure as its first argument.
CHILD = r"""
import contextlib, io, json, statistics, sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import nbformat
import kalman_course
assert kalman_course.__file__.startswith(sys.argv[1]), kalman_course.__file__
from kalman_course import checks
repeats = int(sys.argv[2])
times = {}
for path in sorted(Path(sys.argv[1], "solutions").glob("*.ipynb")):
    nb = nbformat.read(path, as_version=4)
    namespace = {"__name__": path.stem}
    calls = []
    with contextlib.redirect_stdout(io.StringIO()):
        for cell in nb.cells:
            if cell.cell_type != "code":
                continue
            if "grader" in cell.metadata.get("tags", []):
                calls.append(cell.metadata["kalman_course"]["check"])
                continue
            exec(compile(cell.source, str(path), "exec"), namespace)
        plt.close("all")
        for name in calls:
            source = [c.source for c in nb.cells if c.metadata.get("kalman_course", {}).get("check") == name][0]
            obj = eval(source[source.index("(") + 1:source.rindex(")")], namespace)
            check = getattr(checks, name)
            check(obj)                                   # first call: caches, lazy imports
            spent = []
            for _ in range(repeats):
                start = time.perf_counter()
                check(obj)
                spent.append(time.perf_counter() - start)
            times[name] = 1e3 * statistics.median(spent)
print(json.dumps(times))
"""


def measure(tree: Path, repeats: int) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-c", CHILD, str(tree), str(repeats)], check=True,
                         capture_output=True, text=True, cwd=tempfile.gettempdir())
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", nargs="?", help="an earlier commit to compare with (optional)")
    parser.add_argument("--repeats", type=int, default=5, help="timed calls per check (default 5)")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds with a commit (default 3)")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.rounds < 1:
        parser.error("--repeats and --rounds must be at least 1")
    if args.old is None:
        new = measure(ROOT, args.repeats)
        print("| check | ms |\n|---|---|")
        for name, ms in new.items():
            print(f"| {name} | {ms:.2f} |")
        return 0
    with checked_out(args.old) as old_tree:
        olds, news = [], []
        for _ in range(args.rounds):
            olds.append(measure(old_tree, args.repeats))
            news.append(measure(ROOT, args.repeats))
    print(f"| check | {args.old} (ms) | this checkout (ms) | ratio |\n|---|---|---|---|")
    for name in news[0]:
        old = statistics.median(o[name] for o in olds if name in o) if name in olds[0] else float("nan")
        new = statistics.median(n[name] for n in news)
        print(f"| {name} | {old:.2f} | {new:.2f} | {new / old:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
