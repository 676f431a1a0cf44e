"""A pytest plugin that records nbval's per-cell results as JSON for the grader.

``kalman-course grade`` runs ``pytest -p kalman_course.tooling.nbval_results --nbval-lax ...`` in
a subprocess with ``KALMAN_COURSE_RESULTS`` naming the output file. Each entry holds the
notebook's file name, the cell id, its index among code cells, whether it passed and, if not, nbval's report.
"""

from __future__ import annotations

import json
import os

import pytest

_results: list[dict] = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    cell = getattr(item, "cell", None)
    if cell is None or report.when == "teardown" or (report.when == "setup" and report.passed):
        return
    _results.append({
        "file": item.path.name,
        "cell_id": cell.get("id"),
        "index": item.cell_num,
        "passed": report.passed,
        "skipped": report.skipped,
        "message": "" if report.passed else str(report.longrepr),
    })


def pytest_sessionfinish(session, exitstatus):
    path = os.environ.get("KALMAN_COURSE_RESULTS")
    if path:
        with open(path, "w", encoding="utf-8") as fh:
            json.dump(_results, fh)
