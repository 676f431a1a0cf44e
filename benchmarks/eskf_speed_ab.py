"""Time the ESKF over all of sequence 00 for this checkout and an earlier commit, alternately.

Absolute times on shared machines drift within minutes, so a speed change is measured as
old/new pairs run one after the other, each in a fresh process importing its own tree:

    python benchmarks/eskf_speed_ab.py c50d548 --pairs 8

prints every pair, both medians and the median of the pairwise ratios new/old. The earlier
commit is checked out with ``git worktree`` into a temporary folder that is removed after.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from worktree import ROOT, checked_out

# Runs in a child process: the tree to import is its first argument. It handles both the
# layered package and the flat one that preceded it.
CHILD = """
import statistics, sys, time
sys.path.insert(0, sys.argv[1])
import kalman_course
assert kalman_course.__file__.startswith(sys.argv[1]), kalman_course.__file__
from kalman_course.data import load_kitti
try:
    from kalman_course.filters import eskf
except ImportError:
    from kalman_course import eskf
seq = load_kitti("seq00")
k0, s0 = seq.initial_state()
def once():
    start = time.perf_counter()
    eskf.run(seq.imu, s0, "kitti_lidar", seq.gravity, lidar=seq.lidar, start=k0)
    return time.perf_counter() - start
once()
print(statistics.median(once() for _ in range(int(sys.argv[2]))))
"""


def median_seconds(tree: Path, runs: int) -> float:
    out = subprocess.run([sys.executable, "-c", CHILD, str(tree), str(runs)], check=True,
                         capture_output=True, text=True, cwd=tempfile.gettempdir())
    return float(out.stdout.strip())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("old", help="the earlier commit (any git revision)")
    parser.add_argument("--pairs", type=int, default=8, help="old/new pairs (default 8)")
    parser.add_argument("--runs", type=int, default=5, help="timed runs per process (default 5)")
    args = parser.parse_args(argv)
    if args.pairs < 1 or args.runs < 1:
        parser.error("--pairs and --runs must be at least 1")
    with checked_out(args.old) as old_tree:
        old, new = [], []
        for k in range(args.pairs):
            old.append(median_seconds(old_tree, args.runs))
            new.append(median_seconds(ROOT, args.runs))
            print(f"pair {k + 1}: old {old[-1]:.3f} s, new {new[-1]:.3f} s, ratio {new[-1] / old[-1]:.3f}")
    ratios = [n / o for n, o in zip(new, old)]
    print(f"median: old {statistics.median(old):.3f} s, new {statistics.median(new):.3f} s; "
          f"median ratio new/old {statistics.median(ratios):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
