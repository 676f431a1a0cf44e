"""Wall time of grading a class with this checkout and with an earlier commit, alternately.

The class is every exercise and every solution of the tree, twice (two learners), graded
by that tree's own ``kalman-course grade CLASS --release exercises --jobs J`` in a fresh
process whose imports (and those of its kernels) come from that tree:

    python benchmarks/class_throughput.py c50d548 --pairs 3 --jobs 2

prints each pair, both medians, notebooks per minute per core and the median of the
pairwise ratios new/old. The earlier commit is checked out with ``git worktree`` into a
temporary folder that is removed after.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from worktree import ROOT, checked_out

LEARNERS = ("alice", "bob")


def make_class(tree: Path, folder: Path) -> int:
    """Copy every exercise and solution of ``tree`` for each learner; return the count."""
    count = 0
    for learner in LEARNERS:
        for kind in ("exercises", "solutions"):
            target = folder / learner / kind
            target.mkdir(parents=True)
            for path in sorted((tree / kind).glob("[0-9][0-9]_*.ipynb")):
                shutil.copy(path, target / path.name)
                count += 1
    return count


def _entry_point(tree: Path) -> tuple[str, str]:
    """(module, function) of the tree's ``kalman-course`` command (it moved between commits)."""
    text = (tree / "pyproject.toml").read_text(encoding="utf-8")
    spec = re.search(r'^kalman-course\s*=\s*"([\w.]+):(\w+)"', text, re.M)
    if spec is None:
        raise SystemExit(f"{tree}: no kalman-course entry point in pyproject.toml")
    return spec.group(1), spec.group(2)


def grade_seconds(tree: Path, folder: Path, jobs: int) -> float:
    """Wall time of one ``kalman-course grade`` of ``folder`` by ``tree`` (imports from ``tree``)."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    module, function = _entry_point(tree)
    code = (f"import sys; from {module} import {function} as main; "
            f"assert __import__('kalman_course').__file__.startswith({str(tree)!r}); "
            f"sys.exit(main(['grade', {str(folder)!r}, '--release', {str(tree / 'exercises')!r}, "
            f"'--jobs', '{jobs}']))")
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], env=env, cwd=tempfile.gettempdir(),
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", help="the earlier commit (any git revision)")
    parser.add_argument("--pairs", type=int, default=3, help="old/new pairs (default 3)")
    parser.add_argument("--jobs", type=int, default=2, help="grading jobs (default 2)")
    args = parser.parse_args(argv)
    if args.pairs < 1 or args.jobs < 1:
        parser.error("--pairs and --jobs must be at least 1")
    with checked_out(args.old) as old_tree, tempfile.TemporaryDirectory() as tmp:
        classes = {}
        for name, tree in (("old", old_tree), ("new", ROOT)):
            classes[name] = (tree, Path(tmp) / name, make_class(tree, Path(tmp) / name))
        times = {"old": [], "new": []}
        for pair in range(args.pairs):
            for name in ("old", "new"):
                tree, folder, _ = classes[name]
                times[name].append(grade_seconds(tree, folder, args.jobs))
            print(f"pair {pair + 1}: old {times['old'][-1]:.1f} s, new {times['new'][-1]:.1f} s", flush=True)
    cores = min(args.jobs, os.cpu_count() or 1)
    for name in ("old", "new"):
        n, median = classes[name][2], statistics.median(times[name])
        print(f"{name}: {n} notebooks, median {median:.1f} s, "
              f"{n / (median / 60) / cores:.1f} notebooks per minute per core")
    ratios = [new / old for old, new in zip(times["old"], times["new"])]
    print(f"median ratio new/old: {statistics.median(ratios):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
