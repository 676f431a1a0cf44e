"""Grade exercise notebooks: restore grader cells, run the learner's cells, judge outside.

The learner's file is never written to. Each submission's grader cells and grading
metadata are restored from the released exercise (by cell id: each change reported, deleted
graders re-added). Then the learner's cells run in a fresh kernel of their own, in order,
with a per-cell timeout; at each grader cell the check runs in this process and calls the
learner's functions in the kernel, with plain data crossing both ways
(:mod:`kalman_course.checks.remote`). Expected values and comparisons never enter the
learner's kernel, so nothing a learner's cell does there can change a verdict; the grader
cells' own output (the learner's instant feedback in JupyterLab) is not used.
"""

from __future__ import annotations

import ast
import contextlib
import copy
import csv
import io
import json
import re
import threading
import time
import warnings
from dataclasses import asdict, dataclass, field
from pathlib import Path

from kalman_course.tooling.cells import CHECK_OUTPUT_TAG, GRADER_TAG, grader_info, is_challenge
from kalman_course.tooling.notebooks import NotebookError, read_notebook
from kalman_course.tooling.review import review_flags


#: Statuses of a graded notebook. Only GRADED and TAMPERED_RESTORED ran to the end.
GRADED, TAMPERED_RESTORED, TIMED_OUT, KERNEL_DIED, NOT_A_NOTEBOOK, NO_RELEASE, RUN_ERROR, WORKER_DIED = (
    "graded", "tampered and restored", "timed out", "kernel died", "not a notebook", "no release",
    "run error", "grading worker died")
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
    in_kernel: bool | None = None  # the grader cell's own verdict in the kernel (only when compared)
    challenge: bool = False  # an optional challenge: its points are counted apart from the core's


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
    #: its place in the whole class (a shard's gradebook keeps it, so that merging restores the order)
    order: int = 0
    class_size: int = 1
    seconds: float = 0.0  # not in the gradebook: it would differ between two runs

    @property
    def points(self) -> int:
        """The core points: every check but the optional challenges."""
        return sum(c.points for c in self.checks if not c.challenge)

    @property
    def possible(self) -> int:
        return sum(c.possible for c in self.checks if not c.challenge)

    @property
    def challenge_points(self) -> int:
        return sum(c.points for c in self.checks if c.challenge)

    @property
    def challenge_possible(self) -> int:
        return sum(c.possible for c in self.checks if c.challenge)

    @property
    def points_text(self) -> str:
        """``"12/14"``, or ``"12/14 +2/3"`` with the optional challenges' points."""
        text = f"{self.points}/{self.possible}"
        if self.challenge_possible:
            text += f" +{self.challenge_points}/{self.challenge_possible}"
        return text

    @property
    def hint(self) -> str:
        """The first failing core check's message (or the run problem); a challenge left
        undone is no problem to report."""
        if self.status not in RAN_TO_THE_END and self.detail:
            return self.detail
        for c in self.checks:
            if c.points < c.possible and not c.challenge:
                return c.message
        return ""


def chapter_of_notebook(nb, path: Path, known=None) -> str:
    """Chapter from the notebook metadata, else from a ``NN_`` file-name prefix ('' if neither).

    With ``known`` (the released chapters), metadata naming no known chapter gives way to
    the file name (an edited chapter number is restored and reported, not a lost grade).
    """
    meta = nb.metadata.get("kalman_course")
    chapter = str(meta.get("chapter") or "") if isinstance(meta, dict) else ""
    m = re.match(r"^(\d\d)_", path.name)
    by_name = m.group(1) if m else ""
    if chapter and (known is None or chapter in known or by_name not in known):
        return chapter
    return by_name


def load_release(release_dir: str | Path) -> dict:
    """Read the released exercises, keyed by chapter."""
    release_dir = Path(release_dir)
    if not release_dir.is_dir():
        raise FileNotFoundError(f"release folder not found: {release_dir} (pass --release DIR)")
    release = {}
    for path in sorted(release_dir.glob("[0-9][0-9]_*.ipynb")):
        nb = read_notebook(path)
        release[chapter_of_notebook(nb, path)] = nb
    return release


def _describe_tags(before, after) -> str:
    added, removed = sorted(set(after) - set(before)), sorted(set(before) - set(after))
    return ", ".join([f"+{t}" for t in added] + [f"-{t}" for t in removed])


def _success_line(check: str) -> str:
    from kalman_course.checks.harness import SUCCESS

    return SUCCESS.format(name=check) + "\n"


def _honest_outputs(outputs, check: str) -> bool:
    """Whether a grader cell's stored outputs are what running it can print: nothing, the
    success line, or an error (a learner who runs the notebook stores one of these)."""
    kinds = [o.get("output_type") for o in outputs]
    if not outputs:
        return True
    if kinds == ["stream"]:
        return outputs[0].get("name") == "stdout" and outputs[0].get("text") == _success_line(check)
    return kinds == ["error"]


def restore_graders(submission, release):
    """Return a copy of ``submission`` whose grader cells and grading metadata are the release's.

    Every difference that grading would read is restored and described: a grader cell's
    source, type, tags, metadata (its check and points) and stored outputs that running it
    cannot have produced; grading tags or metadata on a learner's own cell (a fake grader);
    the notebook's ``kalman_course`` metadata (a key the release has, changed; a solution
    notebook, which has none of them, is not reported).

    Returns
    -------
    nb : NotebookNode
        The notebook to run.
    tampered : list of str
        One line per restored change, naming the cell id and what was changed.
    readded : list of str
        Ids of grader cells that were missing (now re-inserted where the release has them).
    """
    nb = copy.deepcopy(submission)
    release_ids = [c.get("id") for c in release.cells]
    graders = {c["id"]: c for c in release.cells if grader_info(c)}
    tampered, readded = [], []
    for cell in nb.cells:
        if cell.get("id") in graders:
            continue
        tags = cell.metadata.get("tags", [])
        fake = [t for t in tags if t in (GRADER_TAG, CHECK_OUTPUT_TAG)]
        if fake or "kalman_course" in cell.metadata:
            tampered.append(f"cell {cell.get('id')}: a learner cell carried grader "
                            + ("tags " + ", ".join(fake) if fake else "metadata") + " (removed)")
        cell.metadata["tags"] = [t for t in tags if t not in (GRADER_TAG, CHECK_OUTPUT_TAG)]
        cell.metadata.pop("kalman_course", None)
    position = {c.get("id"): i for i, c in enumerate(nb.cells)}
    for gid, ref in graders.items():
        if gid in position:
            cell = nb.cells[position[gid]]
            check = grader_info(ref)[0]
            changes = []
            if cell.get("cell_type") != ref.cell_type:
                changes.append(f"turned into a {cell.get('cell_type')} cell")
            if cell.get("source") != ref.source:
                changes.append("source edited")
            if sorted(cell.get("metadata", {}).get("tags", [])) != sorted(ref.metadata.get("tags", [])):
                changes.append("tags changed (" + _describe_tags(ref.metadata.get("tags", []),
                                                                 cell.get("metadata", {}).get("tags", [])) + ")")
            if cell.get("metadata", {}).get("kalman_course") != ref.metadata.get("kalman_course"):
                changes.append("grading metadata changed (check or points)")
            if not _honest_outputs(cell.get("outputs", []), check):
                changes.append("stored output edited")
            if changes:
                tampered.append(f"cell {gid}: " + "; ".join(changes))
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
    submitted = nb.metadata.get("kalman_course")
    submitted = submitted if isinstance(submitted, dict) else {}
    released = release.metadata.get("kalman_course", {})
    tampered += [f"notebook metadata kalman_course.{key} changed" for key in released
                 if key in submitted and submitted[key] != released[key]]
    nb.metadata["kalman_course"] = copy.deepcopy(released)
    nb.metadata["kernelspec"] = copy.deepcopy(release.metadata.get("kernelspec", {}))
    return nb, tampered, readded


def grader_call(source: str) -> tuple[str, list[str]]:
    """(check name, learner names) of a released grader cell ``checks.NAME(arg, ...)``.

    Raises
    ------
    ValueError
        If the cell is anything else (the release is broken; ``kalman-course build`` writes
        grader cells of exactly this form).
    """
    try:
        tree = ast.parse(source)
    except SyntaxError:
        tree = None
    node = tree.body[0].value if tree and len(tree.body) == 1 and isinstance(tree.body[0], ast.Expr) else None
    if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
            and isinstance(node.func.value, ast.Name) and node.func.value.id == "checks"
            and not node.keywords and all(isinstance(a, ast.Name) for a in node.args)):
        raise ValueError(f"a released grader cell must read checks.NAME(learner_name, ...), got {source!r}")
    return node.func.attr, [a.id for a in node.args]


@dataclass
class _GraderVerdict:
    passed: bool
    message: str = ""
    in_kernel: bool | None = None  # the grader cell's own verdict, when compared


def _judge(session, check_name: str, names: list[str]) -> tuple[bool, str]:
    """Run check ``check_name`` here, on the learner's functions ``names`` in their kernel."""
    from kalman_course.checks import CheckFailed, registered
    from kalman_course.checks.remote import LearnerFunction

    check = registered().get(check_name)
    if check is None:
        return False, f"no check named {check_name} in this version of the course"
    session.deadline = time.monotonic() + session.timeout
    try:
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            check.judge(*[LearnerFunction(session, name) for name in names])
    except CheckFailed as exc:
        return False, f"CheckFailed: {exc}"
    except Exception as exc:  # a bug in the check, not the learner's: report it plainly
        return False, f"the check could not run ({type(exc).__name__}: {exc})"
    finally:
        session.deadline = None
    return True, ""


def run_graded(nb, *, timeout: float = 120.0, compare: bool = False, session=None):
    """Run a restored notebook in a fresh kernel; judge each grader cell in this process.

    Learner cells run in the kernel in order, up to the last grader cell (what follows it
    cannot change a verdict). At each grader cell, its check runs here,
    calling the learner's functions in the kernel (only plain data crosses); the grader
    cell itself does not run, unless ``compare`` is set, when it also runs in the kernel
    and its own verdict (the success line printed, no error) is recorded next to this one.
    ``session``: a kernel already started for this notebook (:func:`_fresh_session`).

    Returns
    -------
    status : str
        GRADED, TIMED_OUT or KERNEL_DIED.
    verdicts : dict
        grader cell id -> :class:`_GraderVerdict` (cells not reached are missing).
    errors : list of (str, str)
        (cell id, "Name: message") of the learner's cells that raised.
    detail : str
        What went wrong when the status is not GRADED.
    """
    from kalman_course.checks.remote import KernelLost

    verdicts, errors = {}, []
    # the checks (SymPy, the excerpts) are imported while the kernel starts and runs the first cells
    importing = threading.Thread(target=registered_checks, daemon=True)
    importing.start()
    session = session or _fresh_session(timeout)
    code = [cell for cell in nb.cells if cell.cell_type == "code"]
    # cells after the last grader cannot change a verdict: they are not run
    last = max((i for i, cell in enumerate(code) if grader_info(cell)), default=-1)
    try:
        session.wait_until_ready()
        for cell in code[:last + 1]:
            info = grader_info(cell)
            if info is None:
                outcome = session.run_cell(cell.source)
                if outcome.status != "ok":
                    errors.append((cell.get("id"), outcome.error))
                continue
            importing.join()
            passed, message = _judge(session, *grader_call(cell.source))
            verdict = _GraderVerdict(passed, message)
            if compare:
                outcome = session.run_cell(cell.source, capture=True)
                verdict.in_kernel = (outcome.status == "ok"
                                     and outcome.stdout == _success_line(info[0]))
            verdicts[cell["id"]] = verdict
    except KernelLost as lost:
        return lost.status, verdicts, errors, lost.detail
    finally:
        session.close()
    if session.timed_out:
        return TIMED_OUT, verdicts, errors, f"a cell ran longer than {timeout:g} s"
    return GRADED, verdicts, errors, ""


#: A kernel started ahead for the next notebook this process grades (see :func:`grade_many`).
_spare_session = None


def _fresh_session(timeout: float, sandbox=None):
    """A new kernel for one notebook: the one started ahead, if any (and then start the next)."""
    from kalman_course.tooling.kernel_session import KernelSession

    global _spare_session
    session = _spare_session or KernelSession(timeout, sandbox)
    session.timeout = float(timeout)
    if _spare_session is not None:
        _spare_session = KernelSession(timeout, sandbox)
    return session


def _close_spare_session() -> None:
    global _spare_session
    if _spare_session is not None:
        _spare_session.close()
        _spare_session = None


def registered_checks() -> dict:
    """Every check, importing them on first use (SymPy and the excerpts take a moment)."""
    from kalman_course.checks import registered

    return registered()


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
                   learner: str = "-", compare: bool = False, sandbox=None) -> NotebookResult:
    """Grade one submitted notebook against the released exercises (``release`` by chapter).

    ``compare`` also runs each grader cell inside the learner's kernel and records that
    verdict as ``CheckResult.in_kernel`` (the tests use it to prove both ways agree).
    """
    path = Path(path)
    result = NotebookResult(path=str(path), learner=learner)
    start = time.perf_counter()
    try:
        submission = read_notebook(path)
    except FileNotFoundError:
        result.status, result.detail = NOT_A_NOTEBOOK, f"no such file: {path}"
        return result
    except (NotebookError, OSError) as exc:  # corrupt JSON, empty file, not a notebook at all
        result.status, result.detail = NOT_A_NOTEBOOK, f"cannot read it as a notebook: {exc}"
        return result
    grade_submission(submission, release, result, timeout=timeout, compare=compare, sandbox=sandbox)
    result.seconds = time.perf_counter() - start
    return result


def grade_submission(submission, release: dict, result: NotebookResult, *, timeout: float = 120.0,
                     compare: bool = False, sandbox=None) -> NotebookResult:
    """Grade a notebook already read (``result`` names it and receives the outcome)."""
    result.chapter = chapter_of_notebook(submission, Path(result.path), release)
    if result.chapter not in release:
        result.status = NO_RELEASE
        result.detail = f"no released exercise for chapter {result.chapter or '?'}"
        return result
    ref = release[result.chapter]
    session = _fresh_session(timeout, sandbox)  # the kernel starts while the notebook is restored and reviewed
    session.show_notebooks({f"release_{result.chapter}.ipynb": json.dumps(ref),
                            Path(result.path).name: json.dumps(submission)})
    nb, result.tampered, result.readded = restore_graders(submission, ref)
    try:
        result.flags = review_flags(nb, ref)
    except Exception as exc:  # the review is advice: it must never cost a grade
        result.flags = [f"the code review failed ({type(exc).__name__}); read the notebook by hand"]
    result.status, verdicts, errors, result.detail = run_graded(nb, timeout=timeout, compare=compare,
                                                                session=session)
    if result.status == GRADED and (result.tampered or result.readded):
        result.status = TAMPERED_RESTORED
    graders = {cell["id"] for cell in ref.cells if grader_info(cell)}
    result.learner_errors = [f"cell {cid}: {error}" for cid, error in errors if cid not in graders]
    for cell in ref.cells:
        info = grader_info(cell)
        if not info:
            continue
        check, possible = info
        verdict = verdicts.get(cell["id"])
        passed = bool(verdict and verdict.passed)
        message = verdict.message if verdict else "not run"
        result.checks.append(CheckResult(check, cell["id"], possible if passed else 0, possible, message,
                                         verdict.in_kernel if verdict else None, is_challenge(cell)))
    return result


def _grade_one(item):
    """Grade one (path or (file name, notebook), learner) of a class; never raises (one bad
    notebook must not stop the rest)."""
    (source, learner), release, timeout, compare, sandbox = item
    name = source[0] if isinstance(source, tuple) else str(source)
    try:
        if isinstance(source, tuple):
            return grade_submission(source[1], release, NotebookResult(name, learner), timeout=timeout,
                                    compare=compare, sandbox=sandbox)
        return grade_notebook(source, release, timeout=timeout, learner=learner, compare=compare,
                              sandbox=sandbox)
    except Exception as exc:  # a bug here must not lose the rest of the class
        return NotebookResult(name, learner, status=RUN_ERROR, detail=f"{type(exc).__name__}: {exc}")


class GradingInterrupted(Exception):
    """Ctrl-C stopped a class run; every kernel and worker of it has ended.

    ``results`` holds the notebooks graded before it (None for the others).
    """

    def __init__(self, results):
        super().__init__("grading interrupted")
        self.results = results


def grade_many(submissions: list[tuple], release: dict, *, timeout: float = 120.0,
               jobs: int = 1, progress=None, compare: bool = False, order=None,
               class_size: int | None = None, sandbox=None) -> list[NotebookResult]:
    """Grade (path, learner) pairs, ``jobs`` at a time, each in its own kernel.

    A submission may also be given already read, as ((file name, notebook), learner).
    With ``jobs`` > 1 each job is a worker process that grades one notebook after another
    (a fresh kernel for each); a worker that dies costs only the notebook it was grading
    (status WORKER_DIED) and is replaced. ``progress(done, total, result)`` is called as
    each one finishes. One submission's failure never stops the others. ``compare``: see
    :func:`grade_notebook`. ``order`` and ``class_size``: the submissions' places in the
    whole class when they are one shard of it (default: they are the class). ``sandbox``:
    a :class:`kalman_course.tooling.sandbox.Sandbox` each kernel starts in (None: none).

    Raises
    ------
    GradingInterrupted
        On Ctrl-C, within about a second, after ending every worker and kernel.
    """
    items = [(s, release, timeout, compare, sandbox) for s in submissions]
    results: list[NotebookResult | None] = [None] * len(items)
    positions = list(range(len(items))) if order is None else list(order)
    class_size = len(items) if class_size is None else class_size

    def place(i):
        results[i].order, results[i].class_size = positions[i], class_size
        return results[i]

    def finished(i, result, done):
        results[i] = result
        if progress:
            progress(done, len(items), place(i))

    try:
        if jobs <= 1 or len(items) <= 1:
            try:
                for i, item in enumerate(items):
                    finished(i, _grade_one(item), i + 1)
            finally:
                _close_spare_session()
        else:
            from kalman_course.tooling.workers import WorkerPool

            from kalman_course.tooling.kernel_session import close_every_session

            with WorkerPool(min(jobs, len(items)), _grade_one, lambda: _worker_start(sandbox),
                            close_every_session) as pool:
                for done, (i, result) in enumerate(pool.map(items, died=_worker_died), 1):
                    finished(i, result, done)
    except KeyboardInterrupt:
        raise GradingInterrupted([place(i) if r else None for i, r in enumerate(results)]) from None
    return [place(i) for i in range(len(items))]


def _worker_start(sandbox) -> None:
    """Worker set-up of :func:`grade_many`: start a kernel ahead, in the run's sandbox."""
    global _spare_session
    from kalman_course.tooling.kernel_session import KernelSession

    registered_checks()
    _spare_session = KernelSession(120.0, sandbox)


def _worker_died(item, why: str) -> NotebookResult:
    (source, learner) = item[0]
    name = source[0] if isinstance(source, tuple) else str(source)
    return NotebookResult(name, learner, status=WORKER_DIED, detail=f"the grading worker died ({why})")


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
        line = f"chapter {chapter}: {len(rs)} graded, mean {mean:.1f}/{rs[0].possible} points"
        if rs[0].challenge_possible:
            done = sum(r.challenge_points == r.challenge_possible for r in rs)
            line += f"; optional challenge done by {done} of {len(rs)}"
        lines.append(line)
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
            if r.challenge_possible:
                lines += [f"Optional challenge: {r.challenge_points}/{r.challenge_possible} points "
                          "(counted apart from the points above).", ""]
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
                mark = "passed" if c.points == c.possible else ("not done" if c.challenge else "failed")
                label = f"{c.check}** (optional challenge " if c.challenge else f"{c.check}** ("
                lines.append(f"- **{label}{c.points}/{c.possible}): {mark}" + (f" — {c.message}" if c.message else ""))
            lines.append("")
        # grading yourself ("-"): feedback.md, not "-.md"
        safe = "feedback" if learner == "-" else (re.sub(r"[^\w.-]", "_", learner) or "_")
        path = folder / f"{safe}.md"
        path.write_text("\n".join(lines), encoding="utf-8")
        written.append(path)
    return written


def format_table(results: list[NotebookResult], every_hint: bool = False) -> str:
    """Return the points table printed by ``kalman-course grade`` (``every_hint``: also every
    failed check with the first line of its message, notebook by notebook)."""
    rows = [("learner", "chapter", "notebook", "points", "status", "first hint")]
    for r in results:
        hint = r.hint.splitlines()[0] if r.hint else ""
        hint = hint.removeprefix("CheckFailed: ")
        rows.append((r.learner or "-", r.chapter or "?", Path(r.path).name, r.points_text, r.status, hint))
    if all(row[0] == "-" for row in rows[1:]):
        rows = [row[1:] for row in rows]  # grading yourself: no learner column
    ncol = len(rows[0]) - 1
    widths = [max(len(row[i]) for row in rows) for i in range(ncol)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:ncol], widths)) + "  " + row[ncol] for row in rows]
    lines.insert(1, "-" * min(sum(widths) + 2 * ncol + 10, 120))
    total, possible = sum(r.points for r in results), sum(r.possible for r in results)
    lines.append(f"total {total}/{possible} points")
    if any(r.challenge_possible for r in results):
        lines.append("(+a/b: the optional challenges' points, counted apart from the core)")
    for r in results:
        if r.tampered or r.readded:
            lines.append(f"note: {Path(r.path).name}: grader cells restored "
                         f"(edited: {', '.join(r.tampered) or 'none'}; re-added: {', '.join(r.readded) or 'none'})")
        for flag in r.flags:
            lines.append(f"review: {Path(r.path).name}: {flag}")
    if every_hint:
        for r in results:
            failed = [c for c in r.checks if c.points < c.possible]
            if failed:
                lines.append(f"{Path(r.path).name}{f' ({r.learner})' if r.learner != '-' else ''}:")
                for c in failed:
                    text = (c.message.splitlines() or [""])[0].removeprefix("CheckFailed: ")
                    lines.append(f"  {text}" if text.startswith(f"{c.check}:") else f"  {c.check}: {text}")
    return "\n".join(lines)


def write_csv(results: list[NotebookResult], path: str | Path) -> None:
    """Write one row per notebook: learner, chapter, status, points, each check's points, restored cells, review flags."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["learner", "notebook", "chapter", "status", "points", "possible", "challenge_points",
                    "challenge_possible", "checks", "tampered", "readded", "flags", "hint"])
        for r in results:
            w.writerow([r.learner, r.path, r.chapter, r.status, r.points, r.possible, r.challenge_points,
                        r.challenge_possible,
                        ";".join(f"{c.check}={c.points}/{c.possible}" for c in r.checks),
                        ";".join(r.tampered), ";".join(r.readded), " | ".join(r.flags), r.hint])


def shard_of(submissions: list[tuple], k: int, n: int) -> list[int]:
    """The positions in ``submissions`` ((path, learner) pairs) that shard ``k`` of ``n`` grades.

    Learners are dealt round-robin in sorted order, so each learner's notebooks stay in one
    shard (one feedback file each) and the shards differ in size by at most one learner.
    """
    if not 1 <= k <= n:
        raise ValueError(f"shard must be K/N with 1 <= K <= N, got {k}/{n}")
    learners = sorted({learner for _, learner in submissions})
    mine = {learner for i, learner in enumerate(learners) if i % n == k - 1}
    return [i for i, (_, learner) in enumerate(submissions) if learner in mine]


def write_json(results: list[NotebookResult], path: str | Path) -> None:
    """Write the full results (every check's message included) as JSON."""
    data = [dict(asdict(r), points=r.points, possible=r.possible, challenge_points=r.challenge_points,
                 challenge_possible=r.challenge_possible, hint=r.hint) for r in results]
    for record in data:
        del record["seconds"]
        for c in record["checks"]:
            if c["in_kernel"] is None:
                del c["in_kernel"]
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")


def read_json(path: str | Path) -> list[NotebookResult]:
    """The results of a gradebook written by :func:`write_json` (a whole class or one shard).

    Raises
    ------
    ValueError
        If the file is not such a gradebook (the message names the file and what is wrong).
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        names = {f for f in NotebookResult.__dataclass_fields__ if f != "seconds"}
        results = []
        for record in data:
            fields = {k: v for k, v in record.items() if k in names}
            fields["checks"] = [CheckResult(**c) for c in fields.get("checks", [])]
            results.append(NotebookResult(**fields))
    except (OSError, ValueError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path}: not a gradebook written by `kalman-course grade --json` "
                         f"({type(exc).__name__}: {exc})") from None
    return results


def merge_results(shards: list[list[NotebookResult]]) -> list[NotebookResult]:
    """One class's results from its shards' gradebooks, in the order one run gives.

    Raises
    ------
    ValueError
        If the shards are not of one class, overlap, or miss part of it.
    """
    results = [r for shard in shards for r in shard]
    sizes = {r.class_size for r in results}
    if len(sizes) > 1:
        raise ValueError(f"the gradebooks are of different classes (class sizes {sorted(sizes)})")
    orders = sorted(r.order for r in results)
    expected = list(range(sizes.pop() if sizes else 0))
    if orders != expected:
        missing = sorted(set(expected) - set(orders))
        twice = sorted({o for o in orders if orders.count(o) > 1})
        raise ValueError("the gradebooks do not make up one class: "
                         + (f"notebooks {missing[:10]} are missing (a shard not merged?)" if missing else "")
                         + ("; " if missing and twice else "")
                         + (f"notebooks {twice[:10]} are in two gradebooks" if twice else ""))
    return sorted(results, key=lambda r: r.order)
