"""Wall time of grading exercise notebooks with ``kalman-course grade``'s machinery.

Usage: ``python benchmarks/grading_time.py [--repeats 3] [NOTEBOOK ...]`` (default: every
notebook in exercises/). Prints, per notebook, the median over the repeats of the time to
restore its grader cells, run it in a fresh kernel and judge its grader cells from outside.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

from kalman_course.tooling import grading

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("notebooks", nargs="*", type=Path)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--release", type=Path, default=ROOT / "exercises")
    args = parser.parse_args(argv)
    paths = args.notebooks or sorted(args.release.glob("[0-9][0-9]_*.ipynb"))
    release = grading.load_release(args.release)
    medians = []
    print("| notebook | median wall time [s] | runs |")
    print("|---|---|---|")
    for path in paths:
        times = [grading.grade_notebook(path, release).seconds for _ in range(args.repeats)]
        medians.append(statistics.median(times))
        print(f"| {path.name} | {medians[-1]:.2f} | {', '.join(f'{t:.2f}' for t in times)} |", flush=True)
    print(f"\nmedian over notebooks: {statistics.median(medians):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
