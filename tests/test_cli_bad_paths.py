"""Every subcommand on anyone's data: a path that is missing or of the other kind, a file that is
empty, not UTF-8, not JSON, cut short, JSON but not a notebook or gradebook, a notebook of
nbformat 3, without cells or with a cell without a source, a file that cannot be read, and an
output that is already the user's.

Each ends with a short error on stderr that names the path and says what was expected, the
command's exit status, no traceback, and every file of the user's as it was, byte for byte (and
nothing new beside them). Nothing here runs a kernel, measures, downloads or builds SymPy
derivations: a guard fails the test if one of them starts.
"""

import argparse
import builtins
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pytest

from kalman_course.checks import cases, hints
from kalman_course.tooling import bench, cli, gradebook, grading, notebooks


def _notebook(cells) -> bytes:
    """A version-4 notebook of ``cells`` (None: without a cell list)."""
    document = {"nbformat": 4, "nbformat_minor": 5, "metadata": {}}
    if cells is not None:
        document["cells"] = cells
    return json.dumps(document).encode()


def _code_cell(source="x = 1", **fields) -> dict:
    """A code cell (``source=None``: without a source)."""
    cell = {"cell_type": "code", "id": "c1", "metadata": {}, "outputs": [], "execution_count": None, **fields}
    if source is not None:
        cell["source"] = source
    return cell


#: (what the file is, its bytes, what a notebook reader's error says about it)
BAD_FILES = [
    ("empty", b"", "an empty file"),
    ("not UTF-8", '{"nbformat": 4, "cells": ["café"]}'.encode("latin-1"), "not UTF-8"),
    ("not JSON", b"hello, this is plain text\n", "not JSON"),
    ("cut-short JSON", _notebook([_code_cell()])[:40], "cut short"),
    ("JSON but not a notebook", b'{"name": "a list of things", "items": [1, 2]}', "not a notebook"),
    ("nbformat 3", json.dumps({"nbformat": 3, "nbformat_minor": 0, "metadata": {},
                               "worksheets": [{"cells": []}]}).encode(), "nbformat 3, not 4"),
    ("no cells", _notebook(None), "without a list of cells"),
    ("a cell without a source", _notebook([_code_cell(source=None)]), "cell 1 has no source"),
]

#: What every notebook error says was expected.
A_NOTEBOOK = "expected a Jupyter notebook"


def _solution() -> bytes:
    """A solution notebook with one fix region and its grader cell."""
    region = ("def f(x):\n    # BEGIN SOLUTION f_check\n    y = x + 1\n    # STUB\n    # y = x - 1  # fix this\n"
              "    # END SOLUTION\n    return y")
    grader = _code_cell("checks.f_check(f)", id="c2",
                        metadata={"tags": ["grader"], "kalman_course": {"check": "f_check", "points": 2}})
    return _notebook([_code_cell(region), grader])


def _gradebook(path: Path) -> Path:
    """An unsigned gradebook of a class of one (merged with --unsigned)."""
    result = grading.NotebookResult("class/alice/03_kf.ipynb", "alice", "03",
                                    checks=[grading.CheckResult("kf_predict", "g1", 2, 2)])
    run = gradebook.run_record([("alice", result.path)], sandbox="none", seed=1)
    gradebook.write_gradebooks([result], run, None, json_path=path)
    return path


@dataclass
class Case:
    """A command line run on the user's files in ``tmp``: ``setup(tmp)`` writes them and returns
    the arguments, the path the error must name and the files to make unreadable."""

    command: str
    label: str
    setup: Callable
    code: int
    says: str  # what the error must say (the problem, what was expected)

    def __str__(self):
        return f"{self.command}: {self.label}"


def _write(path: Path, data: bytes = b"my own notes\n") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def _folder(path: Path) -> Path:
    path.mkdir(parents=True)
    return path


# --- the cases, command by command ------------------------------------------------------------------

def _execute_cases():
    yield Case("execute", "a missing notebook", lambda t: (["execute", str(t / "gone.ipynb")], t / "gone.ipynb", []),
               2, "no such file; " + A_NOTEBOOK)
    yield Case("execute", "a folder without notebooks", lambda t: (["execute", str(_folder(t / "lecture.ipynb"))],
                                                                    t / "lecture.ipynb", []), 2, "no notebooks found")
    for label, data, says in BAD_FILES:
        yield Case("execute", f"a notebook: {label}", lambda t, d=data: (
            ["execute", str(_write(t / "03_kf.ipynb", d))], t / "03_kf.ipynb", []), 2, says)
    yield Case("execute", "an unreadable notebook", lambda t: (
        ["execute", str(_write(t / "03_kf.ipynb", _solution()))], t / "03_kf.ipynb", [t / "03_kf.ipynb"]),
        2, "cannot be read (permission denied)")


def _build(t, solutions=None, exercises=None, *options):
    return ["build", "--solutions", str(solutions or t / "solutions"), "--exercises", str(exercises or t / "exercises"),
            *options]


def _solutions(t, data=None) -> Path:
    """The user's solutions folder, its ``07_demo.ipynb`` holding ``data`` (a good solution by default)."""
    _write(t / "solutions" / "07_demo.ipynb", _solution() if data is None else data)
    return t / "solutions"


def _build_cases():
    solution = Path("solutions", "07_demo.ipynb")
    yield Case("build", "a missing solutions folder", lambda t: (_build(t), t / "solutions", []),
               2, "no such folder; expected a folder of solution notebooks")
    yield Case("build", "a file as the solutions folder", lambda t: (
        _build(t, _write(t / "solutions")), t / "solutions", []), 2, "a file, not a folder")
    yield Case("build", "a solutions folder without solutions", lambda t: (
        _build(t, _folder(t / "solutions")), t / "solutions", []), 2, "no solution notebooks")
    yield Case("build", "a file as the exercises folder", lambda t: (
        _build(t, _solutions(t), _write(t / "exercises")), t / "exercises", []),
        2, "a file, not a folder; expected the folder the exercises are written to")
    yield Case("build", "an exercises folder inside a file", lambda t: (
        _build(t, _solutions(t), _write(t / "notes") / "exercises"), t / "notes", []), 2, "is a file, not a folder")
    for label, data, says in BAD_FILES:
        yield Case("build", f"a solution: {label}", lambda t, d=data: (
            _build(t, _solutions(t, d)), t / solution, []), 2, says)
    yield Case("build", "an unreadable solution", lambda t: (_build(t, _solutions(t)), t / solution, [t / solution]),
               2, "cannot be read")
    yield Case("build", "a solution whose fix region has no stub", lambda t: (
        _build(t, _solutions(t, _solution().replace(b"# STUB", b"# STAB"))), t / solution, []), 2, "no '# STUB' line")
    yield Case("build", "--check on a solution that is not JSON", lambda t: (
        _build(t, _solutions(t, b"{ oops"), None, "--check"), t / solution, []), 2, "not JSON")

    def folder_in_the_way(t):
        _folder(t / "exercises" / "07_demo.ipynb")
        return _build(t, _solutions(t)), t / "exercises" / "07_demo.ipynb", []
    yield Case("build", "a folder where an exercise goes", folder_in_the_way,
               2, "a folder where the build writes an exercise")

    def learners_work(t):
        _write(t / "exercises" / "07_demo.ipynb", b'{"my": "work"}')
        return _build(t, _solutions(t)), t / "exercises" / "07_demo.ipynb", []
    yield Case("build", "an exercise the user changed (output exists)", learners_work,
               1, "changed since the last build")


def _grade(t, *paths, release=None, options=()):
    release = release or (t / "release" if (t / "release").exists() else _folder(t / "release"))
    return ["grade", *map(str, paths), "--release", str(release), "--no-sandbox", "--seed", "1", "--jobs", "1",
            *map(str, options)]


def _grade_cases():
    yield Case("grade", "a missing submission", lambda t: (_grade(t, t / "03_kf.ipynb"), t / "03_kf.ipynb", []),
               1, "was not graded: no such file")
    yield Case("grade", "a folder without notebooks", lambda t: (_grade(t, _folder(t / "class")), t / "class", []),
               2, "no notebooks found")
    for label, data, says in BAD_FILES:
        yield Case("grade", f"a submission: {label}", lambda t, d=data: (
            _grade(t, _write(t / "03_kf.ipynb", d)), t / "03_kf.ipynb", []), 1, says)
    yield Case("grade", "an unreadable submission", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb", _solution())), t / "03_kf.ipynb", [t / "03_kf.ipynb"]),
        1, "cannot be read (permission denied)")
    yield Case("grade", "a missing release folder", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), release=t / "nowhere"), t / "nowhere", []), 2, "release folder not found")
    yield Case("grade", "a file as the release folder", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), release=_write(t / "exercises.zip")), t / "exercises.zip", []),
        2, "a file, not a folder; expected the folder of the released exercises")
    for label, data, says in BAD_FILES:
        yield Case("grade", f"a released exercise: {label}", lambda t, d=data: (
            _grade(t, _write(t / "03_kf.ipynb"), release=_write(t / "release" / "03_kf.ipynb", d).parent),
            t / "release" / "03_kf.ipynb", []), 2, says)
    yield Case("grade", "--json on the submission (output exists)", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), options=["--json", t / "03_kf.ipynb"]), t / "03_kf.ipynb", []),
        2, "is one of the files being read")
    yield Case("grade", "--feedback on a file", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), options=["--feedback", _write(t / "notes.md")]), t / "notes.md", []),
        2, "is a file, not a folder")
    yield Case("grade", "--csv on a folder", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), options=["--csv", _folder(t / "grades")]), t / "grades", []),
        2, "is a folder")
    yield Case("grade", "--csv inside a file", lambda t: (
        _grade(t, _write(t / "03_kf.ipynb"), options=["--csv", _write(t / "notes.md") / "grades.csv"]),
        t / "notes.md", []), 2, "is a file, not a folder")


NOT_A_GRADEBOOK = "not a gradebook written by `kalman-course grade --json`"


def _merge_cases():
    yield Case("merge", "a missing gradebook", lambda t: (["merge", str(t / "shard-1.json")], t / "shard-1.json", []),
               2, NOT_A_GRADEBOOK + " (no such file)")
    yield Case("merge", "a folder as a gradebook", lambda t: (
        ["merge", str(_folder(t / "shard-1.json"))], t / "shard-1.json", []), 2, "(a folder, not a file)")
    for label, data, _ in BAD_FILES:
        yield Case("merge", f"a gradebook: {label}", lambda t, d=data: (
            ["merge", str(_write(t / "shard-1.json", d))], t / "shard-1.json", []), 2, NOT_A_GRADEBOOK)
    yield Case("merge", "an unreadable gradebook", lambda t: (
        ["merge", str(_gradebook(t / "shard-1.json"))], t / "shard-1.json", [t / "shard-1.json"]),
        2, "cannot be read (permission denied)")
    def mistyped(t):
        document = json.loads(_gradebook(t / "g.json").read_text())
        document["results"][0]["checks"][0]["points"] = "2"
        _write(t / "g.json", json.dumps(document).encode())
        return ["merge", str(t / "g.json"), "--unsigned"], t / "g.json", []
    yield Case("merge", "a gradebook with a mistyped field names the notebook", mistyped, 2,
               "learner 'alice' ('class/alice/03_kf.ipynb'): results[0].checks[0].points is of type str")
    for option, target, says in [("--json", "shard-1.json", "is one of the files being read"),
                                 ("--feedback", "notes.md", "is a file, not a folder"),
                                 ("--csv", "grades", "is a folder"),
                                 ("--csv", "notes.md/grades.csv", "is a file, not a folder")]:
        def setup(t, option=option, target=target):
            shard = _gradebook(t / "shard-1.json")
            _folder(t / "grades")
            _write(t / "notes.md")
            return ["merge", str(shard), "--unsigned", option, str(t / target)], t / target.split("/")[0], []
        yield Case("merge", f"{option} {target} (output exists)", setup, 2, says)


def _export_cases():
    def html(t, *notebooks, out=None):
        return ["export", "notebooks", *map(str, notebooks), "--to", "html", "-o", str(out or t / "site")]

    yield Case("export", "a missing notebook", lambda t: (html(t, t / "gone.ipynb"), t / "gone.ipynb", []),
               2, "no such file; " + A_NOTEBOOK)
    yield Case("export", "a folder without notebooks", lambda t: (html(t, _folder(t / "lectures")), t / "lectures", []),
               2, "no notebooks to export in")
    for label, data, says in BAD_FILES:
        yield Case("export", f"a notebook: {label}", lambda t, d=data: (
            html(t, _write(t / "lecture.ipynb", d)), t / "lecture.ipynb", []), 2, says)
    yield Case("export", "an unreadable notebook", lambda t: (
        html(t, _write(t / "lecture.ipynb", _solution())), t / "lecture.ipynb", [t / "lecture.ipynb"]),
        2, "cannot be read")
    yield Case("export", "-o on a file", lambda t: (
        html(t, _write(t / "lecture.ipynb", _solution()), out=_write(t / "site")), t / "site", []),
        2, "a file, not a folder; expected the folder to export to")
    yield Case("export", "-o inside a file", lambda t: (
        html(t, _write(t / "lecture.ipynb", _solution()), out=_write(t / "notes") / "site"), t / "notes", []),
        2, "is a file, not a folder")
    def users_index(t):
        _write(t / "site" / "index.html", b"<p>mine</p>")
        return html(t, _write(t / "lecture.ipynb", _solution())), t / "site" / "index.html", []
    yield Case("export", "the user's index.html in -o (output exists)", users_index,
               2, "was not written by kalman-course export")
    yield Case("export", "derivations -o on a file", lambda t: (
        ["export", "derivations", "--to", "md", "-o", str(_write(t / "handouts"))], t / "handouts", []),
        2, "a file, not a folder")
    yield Case("export", "the user's derivations.md in -o (output exists)", lambda t: (
        ["export", "derivations", "--to", "md", "-o", str(_write(t / "handouts" / "derivations.md").parent)],
        t / "handouts" / "derivations.md", []), 2, "was not written by kalman-course export")


def _bench_cases():
    yield Case("bench", "--output on a folder", lambda t: (["bench", "--output", str(_folder(t / "results"))],
                                                           t / "results", []), 2, "a folder, not a file")
    yield Case("bench", "--output inside a file", lambda t: (["bench", "--output", str(_write(t / "notes") / "R.md")],
                                                             t / "notes", []), 2, "is a file, not a folder")


def _data_build_cases():
    yield Case("data build", "--out on a file", lambda t: (["data", "build", "--out", str(_write(t / "kitti"))],
                                                           t / "kitti", []), 2, "a file, not a folder")
    yield Case("data build", "--out inside a file", lambda t: (
        ["data", "build", "--out", str(_write(t / "notes") / "kitti")], t / "notes", []), 2, "is a file, not a folder")


CASES = [*_execute_cases(), *_build_cases(), *_grade_cases(), *_merge_cases(), *_export_cases(), *_bench_cases(),
         *_data_build_cases()]


def _leaf_commands(parser: argparse.ArgumentParser, words=()):
    """Every command line's words, ``data build`` for a subcommand of a subcommand."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _leaf_commands(sub, (*words, name))
            return
    yield " ".join(words)


def test_every_subcommand_has_its_bad_path_cases():
    commands = set(_leaf_commands(cli.build_parser()))
    assert commands == {case.command for case in CASES}, \
        "a subcommand without bad-path cases here (or cases of one that is gone)"


# --- running a case ----------------------------------------------------------------------------------

@pytest.fixture(autouse=True)
def nothing_heavy_starts(monkeypatch):
    """No case may get as far as running a kernel, measuring, downloading or deriving."""
    def refuse(what):
        def refused(*args, **kwargs):
            raise AssertionError(f"{what} started on bad input")
        return refused
    import kalman_course.data.build
    from kalman_course.tooling import export, grading as grading_module

    monkeypatch.setattr(notebooks, "run_cells", refuse("a notebook's kernel"))
    monkeypatch.setattr(bench, "report", refuse("the benchmark"))
    monkeypatch.setattr(kalman_course.data.build, "build", refuse("the KITTI download"))
    monkeypatch.setattr(export, "all_derivations", refuse("the SymPy derivations"))
    monkeypatch.setattr(grading_module, "run_graded", refuse("a learner's kernel"))
    monkeypatch.delenv(gradebook.KEY_VARIABLE, raising=False)


def _snapshot(root: Path) -> dict:
    """Every file and folder under ``root``: its bytes, or ``None`` for a folder."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def _unreadable(paths, monkeypatch):
    """Make ``paths`` unreadable; as root (whom permissions do not stop) the notebook reader's
    ``open`` refuses them as the system would refuse anyone else."""
    for path in paths:
        path.chmod(0)
    if os.geteuid() == 0:
        blocked = {Path(p).resolve() for p in paths}

        def guarded_open(file, *args, **kwargs):
            if Path(file).resolve() in blocked:
                raise PermissionError(13, "Permission denied", str(file))
            return builtins.open(file, *args, **kwargs)
        monkeypatch.setattr(notebooks, "open", guarded_open, raising=False)


@pytest.mark.parametrize("case", CASES, ids=str)
def test_a_bad_path_ends_in_a_short_error_naming_it(case, tmp_path, monkeypatch, capsys):
    user = tmp_path / "user"
    user.mkdir()
    monkeypatch.chdir(user)
    argv, named, unreadable = case.setup(user)
    before = _snapshot(user)
    settings = (cases.run_seed(), hints.settings())
    _unreadable(unreadable, monkeypatch)
    try:
        code = cli.main(argv)
    finally:
        for path in unreadable:
            path.chmod(0o644)
    assert (cases.run_seed(), hints.settings()) == settings  # grade's run seed and hint tier are put back
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert code == case.code, err
    assert any(line.startswith("error: ") for line in err.splitlines()), err
    assert str(named) in err and case.says in err, err
    assert len(err.strip().splitlines()) <= 6, err
    assert _snapshot(user) == before, "the user's files changed"
