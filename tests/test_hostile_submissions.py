"""A class of hostile submissions, graded in one run: each gets the status and points it deserves.

Every case starts from a correct chapter-01 notebook (the released exercise with the
solution's code) and breaks it in one way, or saves it as another editor does (those must
be graded as if JupyterLab had saved them). The whole class is graded by the command line
with two jobs, and no submission file may change.
"""

import copy
import hashlib
import json

import nbformat
import pytest
from nbformat.v4 import new_code_cell

from kalman_course.tooling import authoring, cli, grading

from conftest import ROOT
from notebook_editors import colab_no_tags, vscode_4_4

pytestmark = pytest.mark.slow

CHAPTER = "01_bayes_rule.ipynb"
FULL = 8  # points of chapter 01


def _correct():
    exercise = nbformat.read(ROOT / "exercises" / CHAPTER, as_version=4)
    solution = authoring.render(nbformat.read(ROOT / "solutions" / CHAPTER, as_version=4), set())
    sources = {c["id"]: c.source for c in solution.cells}
    for cell in exercise.cells:
        if authoring.grader_info(cell) is None:
            cell.source = sources[cell["id"]]
    return exercise


def _cell(nb, cid):
    return next(c for c in nb.cells if c["id"] == cid)


def _insert_after(nb, cid, source):
    i = [c["id"] for c in nb.cells].index(cid)
    cell = new_code_cell(source)
    cell["id"] = "learner-extra"
    nb.cells.insert(i + 1, cell)
    return nb


def _edit(cid, old, new):
    def change(nb):
        cell = _cell(nb, cid)
        assert old in cell.source, (cid, old)
        cell.source = cell.source.replace(old, new)
        return nb
    return change


def _replace(cid, source):
    def change(nb):
        _cell(nb, cid).source = source
        return nb
    return change


def _delete(cid):
    def change(nb):
        nb.cells = [c for c in nb.cells if c["id"] != cid]
        return nb
    return change


def _rename(cid, new):
    def change(nb):
        _cell(nb, cid)["id"] = new
        return nb
    return change


def _saved_by(editor):
    """The notebook as ``editor`` saves it: its JSON text, written as it is."""
    def change(nb):
        return editor(json.loads(nbformat.writes(nb)))
    return change


# case: (how to break it, expected status, expected points or None when not fixed)
CASES = {
    "exception": (_edit("likelihood", "def sensor_likelihood", 'raise RuntimeError("oops")\ndef sensor_likelihood'),
                  grading.GRADED, 4),
    "infinite_loop": (lambda nb: _insert_after(nb, "setup", "while True:\n    pass"), grading.TIMED_OUT, None),
    "kernel_dies": (lambda nb: _insert_after(nb, "setup", "import os\nos._exit(1)"), grading.KERNEL_DIED, 0),
    "nan_result": (_edit("update", "return posterior", "return posterior * np.nan"), grading.GRADED, 4),
    "wrong_shape": (_edit("predict", "return transition @ belief", "return (transition @ belief)[:, None]"),
                    grading.GRADED, 4),
    "huge_output": (lambda nb: _insert_after(nb, "setup", 'print("x" * 5_000_000)'), grading.GRADED, FULL),
    "warnings": (_edit("update", "    unnormalised =",
                       '    import warnings\n    warnings.warn("careful")\n    print("debug")\n    unnormalised ='),
                 grading.GRADED, FULL),
    "grader_prints_success": (lambda nb: _replace("grader-door_likelihood", 'print("door_likelihood: passed")')(
        _edit("likelihood", "world == z, p_correct, 1.0 - p_correct", "world == z, 1.0 - p_correct, p_correct")(nb)),
        grading.TAMPERED_RESTORED, 4),  # the wrong likelihood also sinks the recursion check
    "grader_deleted": (_delete("grader-histogram_update"), grading.TAMPERED_RESTORED, FULL),
    "cell_id_changed": (_rename("grader-histogram_predict", "my-cell"), grading.TAMPERED_RESTORED, FULL),
    # the reference is withheld while grading: histogram_update earns nothing, and the filter
    # check that uses it blames it
    "imports_reference": (_replace("update", "from kalman_course.filters.bayes import histogram_update"), grading.GRADED,
                          FULL - 4),
    # the patch changes only the kernel's checks (its grader cell prints "passed" there); the
    # grade comes from the grading process, where the wrong (unnormalised) update fails its
    # check and the filter check with it; the review flags the patch as well
    "patches_checks": (lambda nb: _insert_after(
        _edit("update", "unnormalised / unnormalised.sum()", "unnormalised")(nb), "setup",
        "checks.histogram_update = lambda fn: print('histogram_update: passed')"), grading.GRADED, FULL - 4),
    # honest notebooks of other editors: no cell ids at all, Colab's ids and no tags
    "saved_by_vscode_4_4": (_saved_by(vscode_4_4), grading.GRADED, FULL),
    "saved_by_colab": (_saved_by(colab_no_tags), grading.GRADED, FULL),
}
SAVED_BY_OTHER_EDITORS = ("saved_by_vscode_4_4", "saved_by_colab")
RAW = {"corrupt_json": "{ not json", "empty": ""}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    root = tmp_path_factory.mktemp("class")
    for name, (change, _, _) in CASES.items():
        (root / name).mkdir()
        nb = change(copy.deepcopy(_correct()))
        if isinstance(nb, str):  # the text another editor saved
            (root / name / CHAPTER).write_text(nb, encoding="utf-8")
        else:
            nbformat.write(nb, root / name / CHAPTER)
    for name, text in RAW.items():
        (root / name).mkdir()
        (root / name / CHAPTER).write_text(text)
    (root / "other_chapter").mkdir()
    (root / "other_chapter" / CHAPTER).write_bytes((ROOT / "exercises" / "02_gaussians.ipynb").read_bytes())
    digests = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in root.rglob("*.ipynb")}
    out = tmp_path_factory.mktemp("out")
    code = cli.main(["grade", str(root), "--release", str(ROOT / "exercises"), "--jobs", "2", "--timeout", "10",
                     "--json", str(out / "g.json"), "--csv", str(out / "g.csv"), "--feedback", str(out / "fb")])
    document = json.loads((out / "g.json").read_text())
    records = document["results"] if isinstance(document, dict) else document  # a signed gradebook, or a list
    results = {r["learner"]: r for r in records}
    return code, results, digests, out


def test_every_case_is_graded_once_and_the_run_reports_failure(graded):
    code, results, _, _ = graded
    assert code == 1, "some submissions could not be run: the exit status must say so"
    assert set(results) == set(CASES) | set(RAW) | {"other_chapter"}


@pytest.mark.parametrize("name", sorted(CASES))
def test_case_status_and_points(graded, name):
    _, results, _, _ = graded
    _, status, points = CASES[name]
    r = results[name]
    assert r["status"] == status, r["hint"]
    if points is not None:
        assert r["points"] == points, [c["message"] for c in r["checks"]]
    assert r["possible"] == FULL


@pytest.mark.parametrize("name", sorted(RAW))
def test_unreadable_submissions(graded, name):
    assert graded[1][name]["status"] == grading.NOT_A_NOTEBOOK


def test_restorations_are_reported_and_nothing_false_is_said(graded):
    results = graded[1]
    assert results["grader_prints_success"]["tampered"] == ["cell grader-door_likelihood: source edited"]
    assert results["grader_deleted"]["readded"] == ["grader-histogram_update"]
    assert results["cell_id_changed"]["readded"] == ["grader-histogram_predict"]
    assert results["imports_reference"]["tampered"] == [] and results["imports_reference"]["readded"] == []
    for name in SAVED_BY_OTHER_EDITORS:
        assert (results[name]["tampered"], results[name]["readded"], results[name]["learner_errors"]) == ([], [], [])
    assert "grader_prints_success" not in [n for n, r in results.items() if r["points"] == FULL]


def test_shortcuts_are_flagged_for_review_and_honest_work_is_not(graded):
    _, results, _, out = graded
    flagged = {name for name, r in results.items() if r["flags"]}
    assert flagged == {"imports_reference", "patches_checks"}
    assert results["imports_reference"]["flags"] == [
        "cell update: imports `histogram_update` from `kalman_course.filters.bayes` instead of writing it",
        "cell update: calls kalman_course.filters.bayes.histogram_update, the course's own version of a function "
        "the exercise asks for (withheld while grading)"]
    assert results["patches_checks"]["flags"] == [
        "cell learner-extra: assigns to `checks.histogram_update`, part of the grading code"]
    assert "Flagged for review" in (out / "fb" / "patches_checks.md").read_text()
    assert "assigns to `checks.histogram_update`" in (out / "g.csv").read_text()


def test_other_chapter_is_graded_as_what_it_is(graded):
    r = graded[1]["other_chapter"]
    assert (r["chapter"], r["status"], r["points"]) == ("02", grading.GRADED, 0)


def test_submissions_are_never_modified(graded):
    _, _, digests, _ = graded
    assert {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in digests} == digests


def test_feedback_and_gradebook_files(graded):
    _, results, _, out = graded
    feedback = {p.stem: p.read_text() for p in (out / "fb").glob("*.md")}
    assert set(feedback) == set(results)
    assert "door_likelihood" in feedback["exception"] and "RuntimeError" in feedback["exception"]
    assert "restored" in feedback["grader_deleted"]
    rows = (out / "g.csv").read_text().splitlines()
    assert len(rows) == len(results) + 1 and rows[0].startswith("learner,")
