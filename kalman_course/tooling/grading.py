"""Grade exercise notebooks: restore grader cells, run the learner's cells, judge outside.

The learner's file is never written to. Each submission's grader cells and grading
metadata are restored from the released exercise (found by the ids an editor kept, else by
source, tags and grading metadata, :mod:`kalman_course.tooling.identify`: each change
reported, deleted graders re-added). Then the learner's cells run in a fresh kernel of
their own, in order, with a per-cell timeout; at each grader cell the check runs in this
process and calls the learner's functions in the kernel, with plain data crossing both ways
(:mod:`kalman_course.checks.remote`). Expected values and comparisons never enter the
learner's kernel, so nothing a learner's cell does there can change a verdict; the grader
cells' own output (the learner's instant feedback in JupyterLab) is not used.
"""

from __future__ import annotations

import ast
import atexit
import contextlib
import copy
import io
import json
import os
import re
import shutil
import tempfile
import threading
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from kalman_course.tooling.cells import CHECK_OUTPUT_TAG, GRADER_TAG, grader_info, is_challenge
from kalman_course.tooling.copied import copy_flags
from kalman_course.tooling.identify import Identified, cell_metadata, cell_tags, identify_cells, same_code
from kalman_course.tooling.notebooks import NotebookError, read_notebook, require_folder
from kalman_course.tooling.review import review_flags
from kalman_course.tooling import withheld


#: Statuses of a graded notebook. Only GRADED and TAMPERED_RESTORED ran to the end.
GRADED, TAMPERED_RESTORED, TIMED_OUT, KERNEL_DIED, NOT_A_NOTEBOOK, NO_RELEASE, RUN_ERROR, WORKER_DIED = (
    "graded", "tampered and restored", "timed out", "kernel died", "not a notebook", "no release",
    "run error", "grading worker died")
RAN_TO_THE_END = (GRADED, TAMPERED_RESTORED)

#: The largest notebook file graded, in bytes (an exercise with its figures is a few MiB).
MAX_NOTEBOOK = 100 * 2**20

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


def notebook_name(path: Path) -> str:
    """The notebook's own file name: ``03_kf.ipynb`` of ``alice__03_kf.ipynb`` (the part after
    the learner, as :func:`learner_of` reads it) and of ``03_kf.ipynb``."""
    name = Path(path).name
    return name.split(LEARNER_SEPARATOR, 1)[1] if LEARNER_SEPARATOR in name else name


def chapter_of_notebook(nb, path: Path, known=None) -> str:
    """Chapter from the notebook metadata, else from a ``NN_`` file-name prefix ('' if neither).

    The file name is read after the learner's name of the flat class layout
    (``alice__03_kf.ipynb`` is chapter 03), else as it is (``03_kf__v2.ipynb``). With
    ``known`` (the released chapters), metadata naming no known chapter gives way to the
    file name (an edited chapter number is restored and reported, not a lost grade).
    """
    meta = nb.metadata.get("kalman_course")
    chapter = str(meta.get("chapter") or "") if isinstance(meta, dict) else ""
    by_name = ""
    for name in (notebook_name(path), Path(path).name):
        if m := re.match(r"^(\d\d)_", name):
            by_name = m.group(1)
            break
    if chapter and (known is None or chapter in known or by_name not in known):
        return chapter
    return by_name


def load_release(release_dir: str | Path) -> dict:
    """Read the released exercises, keyed by chapter.

    Raises ``FileNotFoundError`` when the folder is missing and an
    :class:`~kalman_course.tooling.notebooks.InputError` naming it when it is a file, or naming
    the exercise that is not a notebook.
    """
    release_dir = Path(release_dir)
    if not release_dir.exists():
        raise FileNotFoundError(f"release folder not found: {release_dir} (pass --release DIR)")
    require_folder(release_dir, "the folder of the released exercises (--release DIR)")
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
    success line, or an error (a learner who runs the notebook stores one of these). Editors
    may store one print in several pieces: consecutive pieces of a stream count as one."""
    if not isinstance(outputs, list):
        return False
    merged = []
    for out in outputs:
        if not isinstance(out, dict):
            return False
        if (out.get("output_type") == "stream" and merged and merged[-1].get("output_type") == "stream"
                and merged[-1].get("name") == out.get("name")
                and isinstance(merged[-1].get("text"), str) and isinstance(out.get("text"), str)):
            merged[-1] = {**merged[-1], "text": merged[-1]["text"] + out["text"]}
        else:
            merged.append(out)
    kinds = [o.get("output_type") for o in merged]
    if not merged:
        return True
    if kinds == ["stream"]:
        return merged[0].get("name") == "stdout" and merged[0].get("text") == _success_line(check)
    return kinds == ["error"]


def _grader_changes(cell, ref, cells: Identified) -> list[str]:
    """What differs in the cell taken as grader ``ref`` that an honest editor cannot have
    changed (an editor that drops tags or grading metadata on every cell drops them here too)."""
    check = grader_info(ref)[0]
    changes = []
    if cell.get("cell_type") != ref.cell_type:
        changes.append(f"turned into a {cell.get('cell_type')} cell")
    if not same_code(cell.get("source", ""), ref.source):
        changes.append("source edited")
    tags, released_tags = cell_tags(cell), ref.metadata.get("tags", [])
    if (tags or not cells.dropped_tags) and sorted(tags) != sorted(released_tags):
        changes.append(f"tags changed ({_describe_tags(released_tags, tags)})")
    meta = cell_metadata(cell)
    if ("kalman_course" in meta or not cells.dropped_grading) and meta.get("kalman_course") != ref.metadata.get(
            "kalman_course"):
        changes.append("grading metadata changed (check or points)")
    if not _honest_outputs(cell.get("outputs", []), check):
        changes.append("stored output edited")
    return changes


def _learner_claims(cell, i: int, cells: Identified, grader_ids: set[str]) -> list[str]:
    """What a learner's cell carried that makes a grader, or names one (each becomes a tamper line)."""
    label, claims = cells.labels[i], []
    fake = [t for t in cell_tags(cell) if t in (GRADER_TAG, CHECK_OUTPUT_TAG)]
    if fake or "kalman_course" in cell_metadata(cell):
        claims.append(f"{label}: a learner cell carried grader "
                      + ("tags " + ", ".join(fake) if fake else "metadata") + " (removed)")
    if cells.ids[i] in grader_ids:
        claims.append(f"{label}: a learner cell carried the id of grader cell {cells.ids[i]} "
                      "(it ran and was reviewed as a learner cell)")
    return claims


def _as_learner_cell(cell, run_id: str) -> None:
    """Make ``cell`` (a copy) a plain learner cell of the notebook that runs."""
    meta = cell.get("metadata")
    if not isinstance(meta, dict):
        meta = cell["metadata"] = {}
    if "tags" in meta:
        meta["tags"] = [t for t in cell_tags(cell) if t not in (GRADER_TAG, CHECK_OUTPUT_TAG)]
    meta.pop("kalman_course", None)
    cell["id"] = run_id


def restore_graders(submission, release, cells: Identified | None = None):
    """Return a copy of ``submission`` whose grader cells and grading metadata are the release's.

    The grader cells are found as :mod:`kalman_course.tooling.identify` says (by a kept id,
    else by source, tags and grading metadata, in release order; ``cells``: that
    identification, if already made). Every difference that grading would read is restored
    and described: a grader cell's source, type, tags, metadata (its check and points) and
    stored outputs that running it cannot have produced; grading tags or metadata on a
    learner's own cell (a fake grader), and a learner cell carrying a grader's id; the
    notebook's ``kalman_course`` metadata (a key the release has, changed; a solution
    notebook, which has none of them, is not reported). Tags and grading metadata that the
    editor dropped on every cell are no change. Every other cell is the learner's, and runs
    under an id of its own (:attr:`Identified.run_ids`).

    Returns
    -------
    nb : NotebookNode
        The notebook to run.
    tampered : list of str
        One line per restored change, naming the cell (its id, or its place when that is
        missing, invalid or not unique) and what was changed.
    readded : list of str
        Ids of grader cells that were missing (now re-inserted where the release has them).
    """
    cells = cells or identify_cells(submission, release)
    grader_ids = {ref["id"] for ref in release.cells if grader_info(ref)}
    nb = copy.deepcopy(submission)
    tampered = []
    for i, cell in enumerate(nb.cells):
        if i not in cells.graders:
            tampered += _learner_claims(cell, i, cells, grader_ids)
            _as_learner_cell(cell, cells.run_ids[i])
            continue
        ref = release.cells[cells.graders[i]]
        if changes := _grader_changes(cell, ref, cells):
            label = cells.labels[i]
            label = label if label == f"cell {ref['id']}" else f"{label}, grader cell {ref['id']}"
            tampered.append(f"{label}: " + "; ".join(changes))
        nb.cells[i] = copy.deepcopy(ref)
    readded = _readd_missing(nb, cells, release)
    submitted = nb.metadata.get("kalman_course")
    submitted = submitted if isinstance(submitted, dict) else {}
    released = release.metadata.get("kalman_course", {})
    tampered += [f"notebook metadata kalman_course.{key} changed" for key in released
                 if key in submitted and submitted[key] != released[key]]
    nb.metadata["kalman_course"] = copy.deepcopy(released)
    nb.metadata["kernelspec"] = copy.deepcopy(release.metadata.get("kernelspec", {}))
    return nb, tampered, readded


def _readd_missing(nb, cells: Identified, release) -> list[str]:
    """Insert (in ``nb``, in place) every released grader that no cell was taken as, after
    the nearest preceding released cell that the notebook has; return their ids."""
    which = [cells.release_index(i) for i in range(len(nb.cells))]  # the released cell each cell is
    found = set(cells.graders.values())
    readded = []
    for r, ref in enumerate(release.cells):
        if not grader_info(ref) or r in found:
            continue
        insert_at = next((which.index(p) + 1 for p in range(r - 1, -1, -1) if p in which), 0)
        nb.cells.insert(insert_at, copy.deepcopy(ref))
        which.insert(insert_at, r)
        readded.append(ref["id"])
    return readded


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


#: What a check says when the learner's function uses a name never defined (harness._undefined_name).
_USES_UNDEFINED = re.compile(r"(\w+) uses (\w+), which is not defined\. Hint: .*$", re.S)


def _undefined(session, names: list[str], cells: list, errors: list, labels: dict) -> str:
    """The message for a grader cell whose function is not defined (its cell raised, or no
    cell defines it), or "" when every name is defined: told as such, naming the cell, not
    as whatever the check would make of a NameError."""
    for name in names:
        if session.describe(name).get("defined"):
            continue
        raised = dict(errors)
        # a cell that does not parse binds nothing; its def line still says what it was for
        written = re.compile(rf"^(def|class)\s+{re.escape(name)}\b|^{re.escape(name)}\s*=", re.M)
        defining = [c for c in cells if name in _top_level_bindings(c.source) or written.search(c.source)]
        label = (lambda c: labels.get(c.get("id"), f"cell {c.get('id')}"))
        failed = [c for c in defining if c.get("id") in raised]
        if failed:
            return (f"{name} is not defined: its cell, {label(failed[-1])}, raised "
                    f"{raised[failed[-1].get('id')]}. Hint: fix that error and run the cell again; the "
                    "check needs the function the cell defines")
        if defining:
            return (f"{name} is not defined when this grader cell runs, although {label(defining[-1])} "
                    "defines it. Hint: was it deleted (del) or the cell's definition skipped?")
        return (f"{name} is not defined: no cell of the notebook defines it. Hint: the exercise's cell "
                "that defines it was deleted, or the function renamed; restore it from the released exercise")
    return ""


def run_graded(nb, *, timeout: float = 120.0, compare: bool = False, session=None, labels: dict | None = None):
    """Run a restored notebook in a fresh kernel; judge each grader cell in this process.

    Learner cells run in the kernel in order, up to the last grader cell (what follows it
    cannot change a verdict). At each grader cell, its check runs here,
    calling the learner's functions in the kernel (only plain data crosses); the grader
    cell itself does not run, unless ``compare`` is set, when it also runs in the kernel
    and its own verdict (the success line printed, no error) is recorded next to this one.
    ``session``: a kernel already started for this notebook (:func:`_fresh_session`);
    ``labels``: run id -> how a message names that cell (default ``cell <id>``).

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
            check_name, names = grader_call(cell.source)
            undefined = _undefined(session, names, code, errors, labels or {})
            passed, message = (False, f"CheckFailed: {check_name}: {undefined}") if undefined else \
                _judge(session, check_name, names)
            uses = _USES_UNDEFINED.search(message)
            if uses and (why := _undefined(session, [uses[2]], code, errors, labels or {})):
                # which cell to fix: "f uses g, which is not defined: its cell, cell 4, raised ..."
                message = (f"CheckFailed: {check_name}: {uses[1]} uses {uses[2]}, which is not defined"
                           + why.removeprefix(f"{uses[2]} is not defined"))
            verdict = _GraderVerdict(passed, message)
            if compare:
                outcome = session.run_cell(cell.source, capture=True)
                verdict.in_kernel = (outcome.status == "ok"
                                     and outcome.stdout == _success_line(info[0]))
            verdicts[cell["id"]] = verdict
        session.reference_calls = _withheld_calls(session, code[:last + 1])
    except KernelLost as lost:
        return lost.status, verdicts, errors, lost.detail
    finally:
        session.close()
    if session.timed_out:
        return TIMED_OUT, verdicts, errors, f"{session.timed_out} ran longer than {timeout:g} s"
    return GRADED, verdicts, errors, ""


def _cell_file(source: str) -> str:
    """The file name ipykernel gives the code of a cell of ``source`` (its folder aside)."""
    from ipykernel.compiler import get_tmp_hash_seed, murmur2_x86

    return f"{murmur2_x86(source, get_tmp_hash_seed())}.py"


def _withheld_calls(session, cells) -> list[tuple[str | None, str, str]]:
    """(run id of the cell to blame or None, file:line, function) of each call of a withheld
    reference the kernel recorded (a learner who silences the record gains nothing: the
    reference still raised).

    The cell to blame is the one whose code called the guard; when the grader called it
    (the learner's function *is* the reference, under an alias), the last cell that binds
    the exercise function's name.
    """
    if not callable(getattr(session, "withheld_calls", None)):
        return []
    by_file = {_cell_file(cell.source): cell for cell in cells}
    blamed = []
    for filename, line, dotted, exercise_function in session.withheld_calls():
        cell = by_file.get(os.path.basename(str(filename)))
        if cell is None or _calls_by_name(cell.source, line, exercise_function):
            # the grader, or the learner's other code, called the exercise function by its name,
            # which an alias bound to the reference: blame the binding
            binding = next((c for c in reversed(cells) if exercise_function in _top_level_bindings(c.source)), None)
            cell = binding if binding is not None else cell
        blamed.append((None if cell is None else cell.get("id"), f"{filename}:{line}", dotted))
    return blamed


def _calls_by_name(source: str, line: int, name: str) -> bool:
    """Whether line ``line`` (from 1) of a cell calls ``name`` as a plain name, ``name(...)``."""
    lines = source.splitlines()
    return 0 < line <= len(lines) and re.search(rf"(?<![\w.]){re.escape(name)}\s*\(", lines[line - 1]) is not None


def _top_level_bindings(source: str) -> set[str]:
    """The names a cell's code binds at its top level (def, class, assignment, import), read
    as IPython runs it (magics turned into calls); none if it does not parse."""
    from IPython.core.inputtransformer2 import TransformerManager

    try:
        tree = ast.parse(TransformerManager().transform_cell(source))
    except (SyntaxError, ValueError):
        return set()
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((alias.asname or alias.name).split(".")[0] for alias in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign, ast.For, ast.With)):
            names.update(n.id for n in ast.walk(node) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store))
    return names


#: A kernel started ahead for the next notebook this process grades, and whether to start
#: one (in :func:`grade_many`'s workers).
_spare_session = None
_start_ahead = False


def _fresh_session(timeout: float, sandbox=None, package: str | None = None):
    """A new kernel for one notebook: the one started ahead, if it runs on ``package``, and
    then start the next."""
    from kalman_course.tooling.kernel_session import KernelSession

    global _spare_session
    if _spare_session is not None and _spare_session.package != package:
        _close_spare_session()
    session = _spare_session or KernelSession(timeout, sandbox, package)
    session.timeout = float(timeout)
    _spare_session = KernelSession(timeout, sandbox, package) if _start_ahead else None
    return session


#: The guarded builds of this run (chapter → package folder) and the folder that holds them.
_GUARDED: dict[str, str] = {}
_GUARDED_ROOT: list[str] = []


def _guarded_root() -> str:
    """The folder of this run's guarded builds, made once (before any worker forks) and
    removed when the process that made it ends."""
    if not _GUARDED_ROOT:
        root = tempfile.mkdtemp(prefix="kalman-guarded-")
        os.chmod(root, 0o755)  # a kernel of its own user id reads its build through it
        owner = os.getpid()
        atexit.register(lambda: os.getpid() == owner and shutil.rmtree(root, ignore_errors=True))
        _GUARDED_ROOT.append(root)
    return _GUARDED_ROOT[0]


def guarded_package(chapter: str, release_notebook) -> str:
    """The package folder a kernel grading ``chapter`` imports: the chapter's references
    withheld (:mod:`kalman_course.tooling.withheld`), built once per run and chapter."""
    if chapter in _GUARDED:
        return _GUARDED[chapter]
    folder = Path(_guarded_root()) / chapter
    if not folder.exists():
        checks = [info[0] for cell in release_notebook.cells if (info := grader_info(cell))]
        functions = withheld.withheld_functions(withheld.functions_to_write(release_notebook), checks)
        staging = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{chapter}-"))
        withheld.build_guarded(staging, functions, chapter)
        os.chmod(staging, 0o755)
        try:
            os.rename(staging, folder)
        except OSError:  # another worker of this run built it first
            shutil.rmtree(staging, ignore_errors=True)
    _GUARDED[chapter] = str(folder / withheld.PACKAGE.name)
    return _GUARDED[chapter]


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


def read_submission(path: Path):
    """``(notebook, "")`` of a submitted file, or ``(None, why)`` when it is not one to grade:
    a symbolic link (a classmate's notebook is not the learner's own), a file too large to
    read whole, a missing or unreadable file, anything but a version-4 notebook."""
    if path.is_symlink():
        return None, "a symbolic link, not a notebook: hand in the file itself"
    if path.is_file() and path.stat().st_size > MAX_NOTEBOOK:  # read whole, it would fill the grader's memory
        return None, (f"{path.stat().st_size / 2**20:.0f} MiB, more than the {MAX_NOTEBOOK // 2**20} MiB "
                      "a notebook may be (clear its outputs and save it again)")
    if not path.exists():
        return None, f"no such file: {path}"
    try:
        return read_notebook(path), ""
    except NotebookError as exc:  # unreadable, corrupt JSON, empty file, not a notebook at all
        return None, f"cannot read it as a notebook: {exc.problem}"


def grade_notebook(path: str | Path, release: dict, *, timeout: float = 120.0,
                   learner: str = "-", compare: bool = False, sandbox=None) -> NotebookResult:
    """Grade one submitted notebook against the released exercises (``release`` by chapter).

    ``compare`` also runs each grader cell inside the learner's kernel and records that
    verdict as ``CheckResult.in_kernel`` (the tests use it to prove both ways agree).
    """
    path = Path(path)
    result = NotebookResult(path=str(path), learner=learner)
    start = time.perf_counter()
    submission, why = read_submission(path)
    if submission is None:
        result.status, result.detail = NOT_A_NOTEBOOK, why
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
    cells = identify_cells(submission, ref)  # before the kernel starts: nothing to clean up if it fails
    # a compared run also runs the grader cells in the kernel, which need the references
    package = None if compare else guarded_package(result.chapter, ref)
    # the kernel starts while the notebook is restored and reviewed
    session = _fresh_session(timeout, sandbox, package)
    session.show_notebooks({f"release_{result.chapter}.ipynb": json.dumps(ref),
                            Path(result.path).name: json.dumps(submission)})
    nb, result.tampered, result.readded = restore_graders(submission, ref, cells)
    try:
        # the submission as written: the review names its cells by their places in the learner's file
        result.flags = review_flags(submission, ref) + copy_flags(submission, ref, cells)
    except Exception as exc:  # the review is advice: it must never cost a grade
        result.flags = [f"the code review failed ({type(exc).__name__}); read the notebook by hand"]
    labels = cells.label_of_run_id()
    result.status, verdicts, errors, result.detail = run_graded(nb, timeout=timeout, compare=compare,
                                                                session=session, labels=labels)
    if result.status == GRADED and (result.tampered or result.readded):
        result.status = TAMPERED_RESTORED
    graders = {cell["id"] for cell in ref.cells if grader_info(cell)}
    result.learner_errors = [f"{labels.get(cid, f'cell {cid}')}: {error}" for cid, error in errors
                             if cid not in graders]
    calls = getattr(session, "reference_calls", None)
    withheld_flags = []
    for cid, where, dotted in calls if isinstance(calls, list) else ():
        place = labels.get(cid, f"cell {cid}") if cid is not None else f"code outside the notebook's cells ({where})"
        withheld_flags.append(f"{place}: calls {dotted}, the course's own version of a function the exercise "
                              "asks for (withheld while grading)")
    result.flags += dict.fromkeys(withheld_flags)  # once per cell and function, however many calls
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

            _guarded_root()  # one folder of guarded builds for every worker
            with WorkerPool(min(jobs, len(items)), _grade_one, lambda: _worker_start(sandbox),
                            close_every_session) as pool:
                for done, (i, result) in enumerate(pool.map(items, died=_worker_died), 1):
                    finished(i, result, done)
    except KeyboardInterrupt:
        raise GradingInterrupted([place(i) if r else None for i, r in enumerate(results)]) from None
    return [place(i) for i in range(len(items))]


def _worker_start(sandbox) -> None:
    """Worker set-up of :func:`grade_many`: the checks imported (the first notebook's kernel
    starts when its chapter is known: it runs on that chapter's guarded build; the next one
    is started ahead)."""
    global _start_ahead
    registered_checks()
    _start_ahead = True


def _worker_died(item, why: str) -> NotebookResult:
    (source, learner) = item[0]
    name = source[0] if isinstance(source, tuple) else str(source)
    return NotebookResult(name, learner, status=WORKER_DIED, detail=f"the grading worker died ({why})")


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
