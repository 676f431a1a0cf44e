"""Mutation testing of the graders: the reference solutions, edited into plausible mistakes.

A solution notebook is run once per test session in this process (grader cells skipped,
matplotlib on Agg), which gives the namespace a learner's notebook would have. A *mutant*
is a small text edit of one cell of that notebook (the reference code with one plausible
learner mistake); an *equivalent* is an edit that stays correct (another way to write the
same thing). To try one, the namespace is copied, the edited cell is run again in the copy and
so are the function and class definitions of every later cell (so a function that calls the
mutated one sees the mutant; the later cells' demo code is not run), and the grader cell's
check is called on the object the grader cell passes, twice: directly, as the grader
cell does in the learner's kernel, and through the plain-data protocol that
``kalman-course grade`` uses from outside the kernel; the two verdicts and messages must be
identical.

The catalogues are ``tests/mutants/chNN.py``; each holds ``MUTANTS``, ``EQUIVALENTS`` and
``EQUIVALENT_MUTANTS`` (edits that cannot change any result, each with the reason).
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib.util
import inspect
import io
import pkgutil
import re
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import nbformat  # noqa: E402

from kalman_course import checks  # noqa: E402
from kalman_course.checks import cases  # noqa: E402
from kalman_course.checks.remote import LearnerFunction, LocalSession  # noqa: E402
from kalman_course.tooling import withheld  # noqa: E402
from kalman_course.tooling.cells import grader_info  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SOLUTIONS = ROOT / "solutions"
CATALOGUES = Path(__file__).resolve().parent / "mutants"


@dataclass(frozen=True)
class Edit:
    """One mistake (or one correct variant) as a text edit of a solution cell.

    Parameters
    ----------
    check : str
        The grader check it targets (``kf_update``).
    old, new : str
        ``old`` must occur exactly once in the cell; it is replaced by ``new``.
    keyword : str
        For a mutant, a word the failure message must contain (case-insensitive) so that
        the hint names the mistake; unused for an equivalent.
    mistake : str
        What the learner did (for a mutant) or what the variant is (for an equivalent).
    cell : str, optional
        Id of the cell to edit; default: the cell whose source holds ``BEGIN SOLUTION <check>``.
    """

    check: str
    old: str
    new: str
    keyword: str = ""
    mistake: str = ""
    cell: str | None = None


@dataclass(frozen=True)
class Equivalent:
    """An edit that cannot change any result the check sees, and why (not a test case)."""

    check: str
    old: str
    new: str
    reason: str
    cell: str | None = None


@dataclass(frozen=True)
class Outcome:
    passed: bool
    message: str


class Solution:
    """A solution notebook run once: its cells, grader calls and resulting namespace."""

    def __init__(self, path: Path):
        self.path = path
        nb = nbformat.read(path, as_version=4)
        self.cells = [c for c in nb.cells if c.cell_type == "code"]
        self.grader_call = {}
        for c in self.cells:
            info = c.metadata.get("kalman_course", {})
            if "grader" in c.metadata.get("tags", []) and "check" in info:
                self.grader_call[info["check"]] = c.source
        self.code = [c for c in self.cells if "grader" not in c.metadata.get("tags", [])]
        self.namespace = {"__name__": f"solution_{path.stem}"}
        with contextlib.redirect_stdout(io.StringIO()):
            for c in self.code:
                self._run(c.id, c.source, self.namespace)
        plt.close("all")

    def _run(self, cell_id: str, source: str, namespace: dict) -> None:
        exec(compile(source, f"<{self.path.name}:{cell_id}>", "exec"), namespace)

    def cell_of(self, edit) -> nbformat.NotebookNode:
        if edit.cell is not None:
            matches = [c for c in self.code if c.id == edit.cell]
        else:
            marker = re.compile(rf"BEGIN SOLUTION {re.escape(edit.check)}\b")
            matches = [c for c in self.code if marker.search(c.source)]
        if len(matches) != 1:
            raise LookupError(f"{self.path.name}: no single cell for {edit.check!r} (cell={edit.cell!r})")
        return matches[0]

    def edited_source(self, edit) -> str:
        cell = self.cell_of(edit)
        count = cell.source.count(edit.old)
        if count != 1:
            raise LookupError(f"{self.path.name}:{cell.id}: {edit.old!r} occurs {count} times, expected once")
        return cell.source.replace(edit.old, edit.new)

    def _redefine(self, cell_id: str, source: str, namespace: dict) -> None:
        """Run only the function and class definitions of a later cell (not its demo code,
        which may fail on a mutant before the check is ever called)."""
        definitions = [node for node in ast.parse(source).body
                       if isinstance(node, (ast.FunctionDef, ast.ClassDef))]
        if definitions:
            module = ast.Module(body=definitions, type_ignores=[])
            exec(compile(module, f"<{self.path.name}:{cell_id}>", "exec"), namespace)

    def grade(self, edit) -> Outcome:
        """Run the check of ``edit.check`` on the solution with ``edit`` applied."""
        cell = self.cell_of(edit)
        source = self.edited_source(edit)
        namespace = dict(self.namespace)
        start = self.code.index(cell)
        with contextlib.redirect_stdout(io.StringIO()):
            self._run(cell.id, source, namespace)
            for later in self.code[start + 1:]:
                self._redefine(later.id, later.source, namespace)
        call = self.grader_call[edit.check]
        argument = call[call.index("(") + 1:call.rindex(")")]
        in_kernel = _verdict(getattr(checks, edit.check), eval(argument, namespace))
        # the same check as `kalman-course grade` runs it: here, on the learner's functions
        # reached through the plain-data protocol (its "kernel" is this namespace), and under a
        # run seed with the chapter's references withheld while they run
        session = GuardedSession(namespace, self.path.stem) if cases.drawing() else LocalSession(namespace)
        from_outside = _verdict(getattr(checks, edit.check), LearnerFunction(session, argument))
        if from_outside != in_kernel:
            raise AssertionError(f"{edit.check} judges {edit.mistake or edit.reason!r} differently from outside "
                                 f"the kernel: inside {in_kernel}, outside {from_outside}")
        return in_kernel


@functools.cache
def withheld_in(stem: str) -> tuple:
    """The package functions a graded kernel of chapter ``stem`` lacks (its guarded build)."""
    release = nbformat.read(ROOT / "exercises" / f"{stem}.ipynb", as_version=4)
    names = [info[0] for cell in release.cells if (info := grader_info(cell))]
    dotted = withheld.withheld_functions(withheld.functions_to_write(release), names)
    return tuple(pkgutil.resolve_name("{}:{}".format(*name.rsplit(".", 1))) for name in sorted(dotted))


def _guard(*args, **kwargs):
    raise __import__("kalman_course.core.withheld", fromlist=["_"]).ReferenceWithheld(
        "a reference of the course is not available while grading")


class GuardedSession(LocalSession):
    """The learner's "kernel" in this process as a graded run has it: while a learner function
    runs, every function the chapter's guarded build withholds raises (its code swapped for a
    guard's, so that aliases and earlier imports reach the guard too)."""

    def __init__(self, namespace: dict, stem: str):
        super().__init__(namespace)
        self.targets = [inspect.unwrap(fn) for fn in withheld_in(stem)]

    def exchange(self, request: str) -> str:
        saved = [(fn, fn.__code__) for fn in self.targets]
        try:
            for fn, _ in saved:
                fn.__code__ = _guard.__code__
            return super().exchange(request)
        finally:
            for fn, code in saved:
                fn.__code__ = code


def _verdict(check, learner_object) -> Outcome:
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            check(learner_object)
    except checks.CheckFailed as exc:
        return Outcome(False, str(exc))
    finally:
        plt.close("all")
    return Outcome(True, "")


@functools.cache
def solution(stem: str) -> Solution:
    return Solution(SOLUTIONS / f"{stem}.ipynb")


def catalogue(path: Path):
    spec = importlib.util.spec_from_file_location(f"mutant_catalogue_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def catalogues() -> dict[str, object]:
    """Every catalogue module, by file stem (``ch03``)."""
    return {p.stem: catalogue(p) for p in sorted(CATALOGUES.glob("ch*.py"))}
