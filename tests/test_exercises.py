"""Every exercise, run in a kernel: solutions pass, exercises fail, stubs fail alone.

These are the guarantees the course makes to learners: a correct notebook earns every
point, the released exercise earns none, and no stub goes unnoticed by its grader. Each
notebook is graded as ``kalman-course grade`` grades (checks outside the kernel) with every
grader cell also run inside the kernel, and the two verdicts must agree: grading from
outside changes no honest learner's points.
"""

import csv
import hashlib
import json
import shutil

import nbformat
import pytest

from kalman_course.checks import cases
from kalman_course.tooling import authoring, cli, grading

from conftest import ROOT

pytestmark = pytest.mark.slow

SOLUTIONS = sorted((ROOT / "solutions").glob("[0-9][0-9]_*.ipynb"))
# Every stub alone fails its check, with a hint that names it: tests/test_mutants.py proves it
# for all of them (each stub is a catalogued mutant, judged in the process and through the
# plain-data protocol). Here, end to end in a kernel as `kalman-course grade` runs it, the
# first and the last stub of every chapter (a kernel per stub for all of them costs minutes).
STUBS = [(path, stub) for path in SOLUTIONS
         for stubs in [authoring.list_stubs(nbformat.read(path, as_version=4))]
         for stub in dict.fromkeys((stubs[0], stubs[-1]))]


def _graders(nb) -> dict[str, str]:
    """Map check name -> grader cell id."""
    return {info[0]: cell["id"] for cell in nb.cells if (info := authoring.grader_info(cell))}


def _variant(kind: str, path, stub=None):
    """The notebook a test runs: the solution, the released exercise, or one stub alone."""
    if kind == "exercise":
        return nbformat.read(ROOT / "exercises" / path.name, as_version=4)
    nb = nbformat.read(path, as_version=4)
    if kind != "stub":
        return nb
    nb = authoring.render(nb, {stub.stub_id})
    # Nothing after the stub's own grader cell can change its verdict: do not run it.
    ids = [c["id"] for c in nb.cells]
    nb.cells = nb.cells[: ids.index(_graders(nb)[stub.check]) + 1]
    return nb


_KINDS = {"test_solution_passes_every_grader": "solution", "test_exercise_fails_every_grader": "exercise",
          "test_each_stub_alone_fails_its_grader": "stub"}


@pytest.fixture(scope="module")
def outcomes(request):
    """Grade every notebook the selected tests need at once: two workers, a kernel each.

    Returns {(kind, file name, stub id or None): (status, detail, {cell id: passed},
    {cell id: passed inside the kernel})}.
    """
    wanted = {}
    for item in request.session.items:
        kind = _KINDS.get(getattr(item, "originalname", None))
        if kind and hasattr(item, "callspec"):
            path, stub = item.callspec.params["path"], item.callspec.params.get("stub")
            wanted[(kind, path.name, stub.stub_id if stub else None)] = (kind, path, stub)
    keys = list(wanted)
    release = grading.load_release(ROOT / "exercises")
    submissions = [((key[1], _variant(*wanted[key])), "-") for key in keys]
    results = grading.grade_many(submissions, release, timeout=120, jobs=2, compare=True)
    return {key: (r.status, r.detail, {c.cell_id: c.points == c.possible for c in r.checks},
                  {c.cell_id: c.in_kernel for c in r.checks}) for key, r in zip(keys, results)}


def _outcome(outcomes, key) -> dict[str, bool]:
    status, detail, cells, in_kernel = outcomes[key]
    assert status in grading.RAN_TO_THE_END, detail
    differ = {cid: (cells[cid], in_kernel[cid]) for cid in cells if in_kernel[cid] is not cells[cid]}
    assert not differ, f"graded outside vs inside the kernel (cell: (outside, inside)): {differ}"
    return cells


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.stem)
def test_solution_passes_every_grader(outcomes, path):
    cells = _outcome(outcomes, ("solution", path.name, None))
    for check, cid in _graders(nbformat.read(path, as_version=4)).items():
        assert cells.get(cid) is True, f"the solution fails grader {check}"


#: The run seed of the guarded grading of the solutions (any seed: the checks draw anew).
GUARDED_SEED = 20261202


@pytest.fixture(scope="module")
def guarded_outcomes():
    """Every solution graded as an instructor's run grades it: on its chapter's guarded build
    of the package (the reference withheld), on inputs drawn from a run seed."""
    release = grading.load_release(ROOT / "exercises")
    submissions = [((path.name, nbformat.read(path, as_version=4)), "-") for path in SOLUTIONS]
    cases.set_run_seed(GUARDED_SEED)
    try:
        results = grading.grade_many(submissions, release, timeout=120, jobs=2)
    finally:
        cases.set_run_seed(None)
    return {path.name: result for path, result in zip(SOLUTIONS, results)}


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.stem)
def test_solution_earns_every_point_with_the_reference_withheld(guarded_outcomes, path):
    result = guarded_outcomes[path.name]
    assert result.status in grading.RAN_TO_THE_END, result.detail
    lost = [(c.check, c.message) for c in result.checks if c.points < c.possible]
    assert not lost, f"the solution loses points on the guarded build under run seed {GUARDED_SEED}: {lost}"
    assert not result.learner_errors, result.learner_errors
    assert not [flag for flag in result.flags if "withheld" in flag], result.flags


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.stem)
def test_exercise_fails_every_grader(outcomes, path):
    cells = _outcome(outcomes, ("exercise", path.name, None))
    for check, cid in _graders(nbformat.read(ROOT / "exercises" / path.name, as_version=4)).items():
        assert cells.get(cid) is False, f"grader {check} passes on the untouched exercise"


@pytest.mark.parametrize("path, stub", STUBS, ids=[f"{p.stem}-{s.check}-{s.stub_id}" for p, s in STUBS])
def test_each_stub_alone_fails_its_grader(outcomes, path, stub):
    cells = _outcome(outcomes, ("stub", path.name, stub.stub_id))
    cid = _graders(nbformat.read(path, as_version=4))[stub.check]
    assert cells.get(cid) is False, f"stub {stub.stub_id} ({stub.stub.strip()!r}) does not fail grader {stub.check}"


def test_grade_restores_a_tampered_grader_and_never_writes_the_submission(tmp_path, capsys):
    name = SOLUTIONS[0].name
    exercise = nbformat.read(ROOT / "exercises" / name, as_version=4)
    check, cid = next(iter(_graders(exercise).items()))
    tampered = exercise.copy()
    for cell in tampered.cells:
        if cell["id"] == cid:
            cell.source = f'print("{check}: passed")'
    sub_dir = tmp_path / "learner"
    sub_dir.mkdir()
    nbformat.write(tampered, sub_dir / name)
    shutil.copy(ROOT / "exercises" / name, tmp_path / name)  # the untouched exercise, for comparison
    digest = hashlib.sha256((sub_dir / name).read_bytes()).hexdigest()

    code = cli.main(["grade", str(sub_dir / name), str(tmp_path / name),
                     "--release", str(ROOT / "exercises"), "--json", str(tmp_path / "g.json")])
    assert code == 0
    tampered_result, untouched_result = json.loads((tmp_path / "g.json").read_text())["results"]
    assert tampered_result["tampered"] == [f"cell {cid}: source edited"]
    assert tampered_result["checks"] == untouched_result["checks"]
    assert tampered_result["points"] == 0 and tampered_result["possible"] > 0
    assert hashlib.sha256((sub_dir / name).read_bytes()).hexdigest() == digest
    out = capsys.readouterr().out
    assert "grader cells restored" in out and f"0/{tampered_result['possible']}" in out


def test_grade_keeps_going_past_a_broken_notebook_and_exits_nonzero(tmp_path):
    (tmp_path / "01_broken.ipynb").write_text("{ not json")
    shutil.copy(ROOT / "exercises" / SOLUTIONS[0].name, tmp_path / SOLUTIONS[0].name)
    out = tmp_path / "g.csv"
    code = cli.main(["grade", str(tmp_path), "--release", str(ROOT / "exercises"), "--csv", str(out)])
    assert code == 1
    rows = {row["notebook"]: row for row in csv.DictReader(out.open())}
    assert len(rows) == 2
    assert rows[str(tmp_path / "01_broken.ipynb")]["status"] == grading.NOT_A_NOTEBOOK
    assert rows[str(tmp_path / SOLUTIONS[0].name)]["status"] == grading.GRADED
