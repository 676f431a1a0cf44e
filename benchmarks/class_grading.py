"""Wall time of grading a class, and of the instructor exports.

Usage: ``python benchmarks/class_grading.py [--learners 30] [--jobs 2] [--chapter 03]``.
Builds a class folder with one submission per learner (the released exercise of the
chapter; every third learner hands in the solution), grades it with
``kalman-course grade --jobs N`` in the sandbox and with ``--no-sandbox``, alternating
(``--rounds`` of each; medians, their ratio and notebooks per minute per core), then times
``kalman-course export`` for derivations (tex, md) and lectures (html).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from contextlib import redirect_stdout
from io import StringIO
from pathlib import Path

from kalman_course.tooling import cli

ROOT = Path(__file__).resolve().parent.parent


def timed(argv: list[str]) -> float:
    start = time.perf_counter()
    with redirect_stdout(StringIO()):
        cli.main(argv)
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--learners", type=int, default=30)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--chapter", default="03")
    parser.add_argument("--rounds", type=int, default=3, help="class runs in the sandbox and without, alternating")
    args = parser.parse_args(argv)
    [exercise] = sorted((ROOT / "exercises").glob(f"{args.chapter}_*.ipynb"))
    solution = ROOT / "solutions" / exercise.name
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for i in range(args.learners):
            folder = tmp / "class" / f"learner{i:02d}"
            folder.mkdir(parents=True)
            shutil.copy(solution if i % 3 == 0 else exercise, folder / exercise.name)
        grade = ["grade", str(tmp / "class"), "--release", str(ROOT / "exercises"), "--jobs", str(args.jobs),
                 "--csv", str(tmp / "g.csv")]
        times = {"in the sandbox": [], "--no-sandbox": []}
        for _ in range(args.rounds):  # alternating, so that the machine's load falls on both alike
            times["in the sandbox"].append(timed(grade))
            times["--no-sandbox"].append(timed(grade + ["--no-sandbox"]))
        rows = []
        cores = min(args.jobs, os.cpu_count() or 1)
        for how, values in times.items():
            median = statistics.median(values)
            rows.append((f"grade {args.learners} submissions of chapter {args.chapter}, --jobs {args.jobs}, {how} "
                         f"(median of {args.rounds}; {60 * args.learners / median / cores:.1f} notebooks/min/core)",
                         median))
        ratio = statistics.median(times["in the sandbox"]) / statistics.median(times["--no-sandbox"])
        print(f"sandbox / no sandbox: {ratio:.2f}")
        rows.append(("export derivations --to tex", timed(["export", "derivations", "--to", "tex", "-o", str(tmp / "d")])))
        rows.append(("export derivations --to md", timed(["export", "derivations", "--to", "md", "-o", str(tmp / "d")])))
        rows.append(("export notebooks --to html (all lectures)",
                     timed(["export", "notebooks", "--to", "html", "-o", str(tmp / "html"), str(ROOT / "notebooks")])))
    print("| task | wall time [s] |\n|---|---|")
    for name, seconds in rows:
        print(f"| {name} | {seconds:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
