"""Grade exercise notebooks: restore grader cells, run under nbval, count points.

The learner's file is never written to. Each submission is copied into a temporary
folder, its grader cells are restored from the released exercise (by cell id: edited
ones replaced and reported, deleted ones re-added), and the copy is run by nbval in a
subprocess with its own kernel and a per-cell timeout. A grader cell earns its points
when nbval passes it: it ran without error and printed exactly the stored success line.
"""

from __future__ import annotations

import copy
import csv
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import nbformat

from kalman_course.tooling.authoring import CHECK_OUTPUT_TAG, GRADER_TAG, IGNORE_OUTPUT_TAG, grader_info
from kalman_course.tooling.review import review_flags

ANSI_RE = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
EXCEPTION_LINE_RE = re.compile(r"^\s*([A-Za-z_][\w.]*(?:Error|Failed|Exception|Interrupt)): (.+)$", re.M)

#: Statuses of a graded notebook. Only GRADED and TAMPERED_RESTORED ran to the end.
GRADED, TAMPERED_RESTORED, TIMED_OUT, KERNEL_DIED, NOT_A_NOTEBOOK, NO_RELEASE, RUN_ERROR = (
    "graded", "tampered and restored", "timed out", "kernel died", "not a notebook", "no release",
    "run error")
RAN_TO_THE_END = (GRADED, TAMPERED_RESTORED)

#: In a class folder, ``alice__03_kalman_filter.ipynb`` belongs to learner ``alice``.
LEARNER_SEPARATOR = "__"


@dataclass
class CheckResult:
    """One grader cell's outcome."""

    check: str
    cell_id: str
    points: int
    possible: int
    message: str = ""


@dataclass
class NotebookResult:
    """The outcome of grading one notebook."""

    path: str
    learner: str = ""
    chapter: str = ""
    status: str = GRADED
    checks: list[CheckResult] = field(default_factory=list)
    tampered: list[str] = field(default_factory=list)
    readded: list[str] = field(default_factory=list)
    learner_errors: list[str] = field(default_factory=list)
    flags: list[str] = field(default_factory=list)
    detail: str = ""
    seconds: float = 0.0

    @property
    def points(self) -> int:
        return sum(c.points for c in self.checks)

    @property
    def possible(self) -> int:
        return sum(c.possible for c in self.checks)

    @property
    def hint(self) -> str:
        """The first line of the first failing check's message (or the run problem)."""
        if self.status not in RAN_TO_THE_END and self.detail:
            return self.detail
        for c in self.checks:
            if c.points < c.possible:
                return c.message
        return ""


def exception_summary(report: str) -> str:
    """Return the most telling line of an nbval failure report (the last exception raised)."""
    text = ANSI_RE.sub("", report)
    found = EXCEPTION_LINE_RE.findall(text)
    if found:
        name, msg = found[-1]
        return f"{name.rsplit('.', 1)[-1]}: {msg.strip()}"
    if "mismatch" in text.lower():
        return "output differs from the expected success line"
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0] if lines else "failed"


def chapter_of_notebook(nb, path: Path) -> str:
    """Chapter from the notebook metadata, else from a ``NN_`` file-name prefix ('' if neither)."""
    chapter = nb.metadata.get("kalman_course", {}).get("chapter")
    if chapter:
        return str(chapter)
    m = re.match(r"^(\d\d)_", path.name)
    return m.group(1) if m else ""


def load_release(release_dir: str | Path) -> dict[str, nbformat.NotebookNode]:
    """Read the released exercises, keyed by chapter."""
    release_dir = Path(release_dir)
    if not release_dir.is_dir():
        raise FileNotFoundError(f"release folder not found: {release_dir} (pass --release DIR)")
    release = {}
    for path in sorted(release_dir.glob("[0-9][0-9]_*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        release[chapter_of_notebook(nb, path)] = nb
    return release


def restore_graders(submission, release):
    """Return a copy of ``submission`` whose grader cells are exactly the release's.

    Returns
    -------
    nb : NotebookNode
        The notebook to run.
    tampered : list of str
        Ids of grader cells whose source had been changed (now restored).
    readded : list of str
        Ids of grader cells that were missing (now re-inserted where the release has them).
    """
    nb = copy.deepcopy(submission)
    release_ids = [c.get("id") for c in release.cells]
    graders = {c["id"]: c for c in release.cells if grader_info(c)}
    tampered, readded = [], []
    # Learner cells may carry any tags; make sure none is graded or skipped by nbval.
    for cell in nb.cells:
        if cell.cell_type == "code" and cell.get("id") not in graders:
            tags = [t for t in cell.metadata.get("tags", [])
                    if t not in (GRADER_TAG, CHECK_OUTPUT_TAG) and not t.startswith("nbval")]
            cell.metadata["tags"] = tags + [IGNORE_OUTPUT_TAG]
            cell.metadata.pop("kalman_course", None)
    position = {c.get("id"): i for i, c in enumerate(nb.cells)}
    for gid, ref in graders.items():
        if gid in position:
            if nb.cells[position[gid]].source != ref.source:
                tampered.append(gid)
            nb.cells[position[gid]] = copy.deepcopy(ref)
            continue
        # Re-insert after the nearest preceding release cell that the submission still has.
        insert_at = 0
        for prev in reversed(release_ids[:release_ids.index(gid)]):
            if prev in position:
                insert_at = position[prev] + 1
                break
        nb.cells.insert(insert_at, copy.deepcopy(ref))
        readded.append(gid)
        position = {c.get("id"): i for i, c in enumerate(nb.cells)}
    nb.metadata["kernelspec"] = copy.deepcopy(release.metadata.get("kernelspec", {}))
    return nb, tampered, readded


def run_notebook(nb, *, timeout: float = 120.0) -> tuple[str, list[dict], str]:
    """Run ``nb`` under ``pytest --nbval-lax`` in a fresh kernel, in a temporary folder.

    Parameters
    ----------
    nb : NotebookNode
        The notebook (already restored); it is written to a temporary copy only.
    timeout : float
        Per-cell timeout in seconds.

    Returns
    -------
    status : str
        GRADED, TIMED_OUT, KERNEL_DIED or RUN_ERROR.
    cells : list of dict
        nbval's per-code-cell results (cell_id, index, passed, message).
    detail : str
        What went wrong when the status is not GRADED.
    """
    return run_notebooks([nb], timeout=timeout)[0]


def run_notebooks(nbs: list, *, timeout: float = 120.0, jobs: int = 1) -> list[tuple[str, list[dict], str]]:
    """Run several notebooks, each in its own kernel, in ``jobs`` parallel pytest processes.

    Sharing one pytest process between notebooks saves its start-up time; each notebook
    still gets a fresh kernel. Returns one (status, cells, detail) per notebook, as
    :func:`run_notebook` does.
    """
    jobs = max(1, min(jobs, len(nbs)))
    with tempfile.TemporaryDirectory(prefix="kalman-grade-") as tmp:
        tmp = Path(tmp)
        (tmp / "pytest.ini").write_text("[pytest]\n", encoding="utf-8")
        names = [f"submission_{i:03d}.ipynb" for i in range(len(nbs))]
        for nb, name in zip(nbs, names):
            nbformat.write(nb, tmp / name)
        procs = []
        for job in range(jobs):
            chunk = names[job::jobs]
            results = tmp / f"results_{job}.json"
            cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--color=no",
                   "-p", "kalman_course.tooling.nbval_results", "--nbval-lax", "--nbval-current-env",
                   f"--nbval-cell-timeout={timeout:g}", "-c", str(tmp / "pytest.ini"),
                   "--rootdir", str(tmp), *chunk]
            env = dict(os.environ, KALMAN_COURSE_RESULTS=str(results))
            env.pop("MPLBACKEND", None)  # the kernel picks its inline backend, as in JupyterLab
            proc = subprocess.Popen(cmd, cwd=tmp, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    text=True, start_new_session=True)
            n_code = sum(c.cell_type == "code" for i in range(job, len(nbs), jobs) for c in nbs[i].cells)
            procs.append((proc, chunk, results, time.monotonic() + timeout * max(n_code, 1) + 60))
        outcome: dict[str, tuple[str, list[dict], str]] = {}
        for proc, chunk, results, deadline in procs:
            try:
                out, _ = proc.communicate(timeout=max(deadline - time.monotonic(), 1))
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)  # the kernels are in this process group too
                proc.communicate()
                outcome.update({name: (TIMED_OUT, [], "the whole notebook ran out of time") for name in chunk})
                continue
            if not results.exists():
                detail = "nbval did not run: " + (out.strip().splitlines() or ["no output"])[-1]
                outcome.update({name: (RUN_ERROR, [], detail) for name in chunk})
                continue
            cells = json.loads(results.read_text(encoding="utf-8"))
            for name in chunk:
                outcome[name] = _notebook_status([c for c in cells if c["file"] == name], timeout)
    return [outcome[name] for name in names]


def _notebook_status(cells: list[dict], timeout: float) -> tuple[str, list[dict], str]:
    """Tell from nbval's cell reports whether the notebook ran to the end."""
    messages = " ".join(c["message"] for c in cells)
    # A dead kernel first shows as a timeout of the cell that killed it (nbval only waits
    # for a reply), then as "Kernel dead" on every later cell: test for that first.
    if re.search(r"Kernel (?:dead|died)", messages, re.I):
        return KERNEL_DIED, cells, "the kernel died (os._exit, a crash, or out of memory)"
    if "Timeout of" in messages:
        return TIMED_OUT, cells, f"a cell ran longer than {timeout:g} s"
    return GRADED, cells, ""


def learner_of(path: Path, root: Path | None = None) -> str:
    """Name the learner a submission belongs to.

    In a class folder ``root``, a notebook inside a sub-folder belongs to that sub-folder's
    learner (``root/alice/03_kf.ipynb`` → ``alice``); a notebook directly in ``root`` is named
    ``<learner>__<notebook>`` (``root/alice__03_kf.ipynb`` → ``alice``). A file given on its
    own uses the same file-name rule, and is ``"-"`` (yourself) without it.
    """
    path = Path(path)
    if root is not None:
        parts = path.relative_to(root).parts
        if len(parts) > 1:
            return parts[0]
    if LEARNER_SEPARATOR in path.name:
        return path.name.split(LEARNER_SEPARATOR, 1)[0]
    return "-"


def grade_notebook(path: str | Path, release: dict, *, timeout: float = 120.0,
                   learner: str = "-") -> NotebookResult:
    """Grade one submitted notebook against the released exercises (``release`` by chapter)."""
    path = Path(path)
    result = NotebookResult(path=str(path), learner=learner)
    start = time.perf_counter()
    try:
        submission = nbformat.read(path, as_version=4)
        nbformat.validate(submission)
    except Exception as exc:  # corrupt JSON, empty file, not a notebook at all
        result.status, result.detail = NOT_A_NOTEBOOK, f"cannot read it as a notebook ({type(exc).__name__})"
        return result
    result.chapter = chapter_of_notebook(submission, path)
    if result.chapter not in release:
        result.status = NO_RELEASE
        result.detail = f"no released exercise for chapter {result.chapter or '?'}"
        return result
    ref = release[result.chapter]
    nb, result.tampered, result.readded = restore_graders(submission, ref)
    try:
        result.flags = review_flags(nb, ref)
    except Exception as exc:  # the review is advice: it must never cost a grade
        result.flags = [f"the code review failed ({type(exc).__name__}); read the notebook by hand"]
    result.status, cells, result.detail = run_notebook(nb, timeout=timeout)
    if result.status == GRADED and (result.tampered or result.readded):
        result.status = TAMPERED_RESTORED
    by_id = {c["cell_id"]: c for c in cells}
    graders = {cell["id"] for cell in ref.cells if grader_info(cell)}
    result.learner_errors = [f"cell {c['cell_id']}: {exception_summary(c['message'])}"
                             for c in cells if not c["passed"] and c["cell_id"] not in graders]
    for cell in ref.cells:
        info = grader_info(cell)
        if not info:
            continue
        check, possible = info
        outcome = by_id.get(cell["id"])
        passed = bool(outcome and outcome["passed"])
        message = "" if passed else (exception_summary(outcome["message"]) if outcome else "not run")
        result.checks.append(CheckResult(check, cell["id"], possible if passed else 0, possible, message))
    result.seconds = time.perf_counter() - start
    return result


def grade_many(submissions: list[tuple[Path, str]], release: dict, *, timeout: float = 120.0,
               jobs: int = 1, progress=None) -> list[NotebookResult]:
    """Grade (path, learner) pairs, ``jobs`` at a time, each in its own kernel.

    ``progress(done, total, result)`` is called as each one finishes. One submission's
    failure (even an unexpected error in the grader itself) never stops the others.
    """
    from concurrent.futures import ThreadPoolExecutor, as_completed

    def one(path, learner):
        try:
            return grade_notebook(path, release, timeout=timeout, learner=learner)
        except Exception as exc:  # a bug here must not lose the rest of the class
            return NotebookResult(str(path), learner, status=RUN_ERROR, detail=f"{type(exc).__name__}: {exc}")

    results: list[NotebookResult | None] = [None] * len(submissions)
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = {pool.submit(one, path, learner): i for i, (path, learner) in enumerate(submissions)}
        for done, future in enumerate(as_completed(futures), 1):
            results[futures[future]] = future.result()
            if progress:
                progress(done, len(submissions), results[futures[future]])
    return results


def format_summary(results: list[NotebookResult]) -> str:
    """Counts per status and the mean points per chapter."""
    from collections import Counter, defaultdict

    counts = Counter(r.status for r in results)
    lines = ["submissions: " + ", ".join(f"{n} {status}" for status, n in sorted(counts.items()))]
    flagged = sum(1 for r in results if r.flags)
    if flagged:
        lines.append(f"flagged for review: {flagged} (the 'review:' lines, the gradebook's flags column)")
    by_chapter = defaultdict(list)
    for r in results:
        if r.status in RAN_TO_THE_END:
            by_chapter[r.chapter].append(r)
    for chapter, rs in sorted(by_chapter.items()):
        mean = sum(r.points for r in rs) / len(rs)
        lines.append(f"chapter {chapter}: {len(rs)} graded, mean {mean:.1f}/{rs[0].possible} points")
    return "\n".join(lines)


def write_feedback(results: list[NotebookResult], folder: str | Path) -> list[Path]:
    """Write one Markdown feedback file per learner with every failed check's message."""
    from collections import defaultdict

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    per_learner = defaultdict(list)
    for r in results:
        per_learner[r.learner or "-"].append(r)
    written = []
    for learner, rs in sorted(per_learner.items()):
        lines = [f"# Feedback for {learner}", ""]
        for r in sorted(rs, key=lambda r: (r.chapter, r.path)):
            lines += [f"## Chapter {r.chapter or '?'}: `{Path(r.path).name}`", "",
                      f"{r.points}/{r.possible} points — {r.status}", ""]
            if r.status not in RAN_TO_THE_END:
                lines += [f"The notebook could not be graded to the end: {r.detail}.", ""]
            if r.tampered or r.readded:
                lines += ["Grader cells were restored from the released exercise before grading "
                          f"(edited: {', '.join(r.tampered) or 'none'}; missing: {', '.join(r.readded) or 'none'}).", ""]
            if r.flags:
                lines += ["Flagged for review by hand (the points above are what the checks gave):", ""]
                lines += [f"- {flag}" for flag in r.flags] + [""]
            for error in r.learner_errors:
                lines.append(f"- your {error}")
            if r.learner_errors:
                lines.append("")
            for c in r.checks:
                mark = "passed" if c.points == c.possible else "failed"
                lines.append(f"- **{c.check}** ({c.points}/{c.possible}): {mark}" + (f" — {c.message}" if c.message else ""))
            lines.append("")
        safe = re.sub(r"[^\w.-]", "_", learner) or "_"
        path = folder / f"{safe}.md"
        path.write_text("\n".join(lines), encoding="utf-8")
        written.append(path)
    return written


def format_table(results: list[NotebookResult]) -> str:
    """Return the points table printed by ``kalman-course grade``."""
    rows = [("learner", "chapter", "notebook", "points", "status", "first hint")]
    for r in results:
        hint = r.hint.splitlines()[0] if r.hint else ""
        hint = hint.removeprefix("CheckFailed: ")
        rows.append((r.learner or "-", r.chapter or "?", Path(r.path).name, f"{r.points}/{r.possible}",
                     r.status, hint))
    if all(row[0] == "-" for row in rows[1:]):
        rows = [row[1:] for row in rows]  # grading yourself: no learner column
    ncol = len(rows[0]) - 1
    widths = [max(len(row[i]) for row in rows) for i in range(ncol)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:ncol], widths)) + "  " + row[ncol] for row in rows]
    lines.insert(1, "-" * min(sum(widths) + 2 * ncol + 10, 120))
    total, possible = sum(r.points for r in results), sum(r.possible for r in results)
    lines.append(f"total {total}/{possible} points")
    for r in results:
        if r.tampered or r.readded:
            lines.append(f"note: {Path(r.path).name}: grader cells restored "
                         f"(edited: {', '.join(r.tampered) or 'none'}; re-added: {', '.join(r.readded) or 'none'})")
        for flag in r.flags:
            lines.append(f"review: {Path(r.path).name}: {flag}")
    return "\n".join(lines)


def write_csv(results: list[NotebookResult], path: str | Path) -> None:
    """Write one row per notebook: learner, chapter, status, points, each check's points, restored cells, review flags."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["learner", "notebook", "chapter", "status", "points", "possible", "checks",
                    "tampered", "readded", "flags", "hint"])
        for r in results:
            w.writerow([r.learner, r.path, r.chapter, r.status, r.points, r.possible,
                        ";".join(f"{c.check}={c.points}/{c.possible}" for c in r.checks),
                        ";".join(r.tampered), ";".join(r.readded), " | ".join(r.flags), r.hint])


def write_json(results: list[NotebookResult], path: str | Path) -> None:
    """Write the full results (every check's message included) as JSON."""
    data = [dict(asdict(r), points=r.points, possible=r.possible, hint=r.hint) for r in results]
    Path(path).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
