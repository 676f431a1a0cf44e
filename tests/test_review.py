"""Tests for kalman_course.tooling.review: what gets flagged, and that honest work never is."""

import copy

import nbformat
import pytest
from nbformat.v4 import new_code_cell

from kalman_course.tooling import authoring
from kalman_course.tooling.review import review_flags

from conftest import ROOT

CHAPTERS = sorted(p.name for p in (ROOT / "exercises").glob("[0-9]*.ipynb"))


def _release(chapter):
    return nbformat.read(ROOT / "exercises" / chapter, as_version=4)


def _solved(chapter):
    """The released exercise with the solution's code in every non-grader cell."""
    exercise = _release(chapter)
    solution = authoring.render(nbformat.read(ROOT / "solutions" / chapter, as_version=4), set())
    sources = {c["id"]: c.source for c in solution.cells}
    for cell in exercise.cells:
        if authoring.grader_info(cell) is None and cell["id"] in sources:
            cell.source = sources[cell["id"]]
    return exercise


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_honest_notebooks_are_not_flagged(chapter):
    """The release, the solved exercise and the solution notebook itself raise no flag."""
    release = _release(chapter)
    assert review_flags(release, release) == []
    assert review_flags(_solved(chapter), release) == []
    assert review_flags(nbformat.read(ROOT / "solutions" / chapter, as_version=4), release) == []


CH01 = "01_bayes_rule.ipynb"


def _with_update_cell(source):
    nb = _solved(CH01)
    next(c for c in nb.cells if c["id"] == "update").source = source
    return nb


def _with_extra_cell(source):
    nb = _solved(CH01)
    cell = new_code_cell(source)
    cell["id"] = "extra"
    nb.cells.insert(1, cell)
    return nb


CASES = [
    (_with_update_cell("from kalman_course.filters.bayes import histogram_update"),
     "cell update: imports `histogram_update` from `kalman_course.filters.bayes` instead of writing it"),
    (_with_update_cell("from kalman_course.filters.bayes import histogram_update as ref\n"
                       "def histogram_update(b, l):\n    return ref(b, l)"),
     "cell update: imports `histogram_update` from `kalman_course.filters.bayes` instead of writing it"),
    (_with_update_cell("import kalman_course.filters.bayes as kb\nhistogram_update = kb.histogram_update"),
     "cell update: binds `histogram_update` to `kb.histogram_update` instead of writing it"),
    (_with_update_cell("import kalman_course.filters.bayes\n"
                       "def histogram_update(belief, likelihood):\n"
                       "    return kalman_course.filters.bayes.histogram_update(belief, likelihood)"),
     "cell update: `histogram_update` calls `kalman_course.filters.bayes.histogram_update` instead of doing the work"),
    (_with_extra_cell("checks.histogram_update = lambda f: print('histogram_update: passed')"),
     "cell extra: assigns to `checks.histogram_update`, part of the grading code"),
    (_with_extra_cell("from kalman_course.checks import harness\nharness.call = lambda fn, *a, **k: None"),
     "cell extra: assigns to `harness.call`, part of the grading code"),
    (_with_extra_cell("from kalman_course.checks import harness\nharness.call = lambda fn, *a, **k: None"),
     "cell extra: imports `harness` from `kalman_course.checks`"),
    (_with_extra_cell("import kalman_course.checks.bayes as cb\nsetattr(cb, 'CORRIDOR', None)"),
     "cell extra: calls `setattr` on `cb`, part of the grading code"),
    (_with_extra_cell("import sys\nsys.modules['kalman_course.checks'].door_likelihood = print"),
     "cell extra: uses `sys.modules`"),
    (_with_extra_cell("import importlib\n%matplotlib inline\n!echo hi"), "cell extra: imports `importlib`"),
    (_with_extra_cell("__builtins__.print = None"), "cell extra: uses `__builtins__`"),
]


@pytest.mark.parametrize("nb,expected", CASES, ids=[f"case{i}" for i in range(len(CASES))])
def test_shortcuts_are_flagged(nb, expected):
    assert expected in review_flags(nb, _release(CH01))


def test_release_imports_are_not_flagged_but_new_ones_are():
    """The setup cell imports kalman_course.checks in the release; a learner's extra import is new."""
    nb = _solved(CH01)
    setup = next(c for c in nb.cells if c["id"] == "setup")
    setup.source += "\nfrom kalman_course.checks.harness import CheckFailed"
    flags = review_flags(nb, _release(CH01))
    assert flags == ["cell setup: imports `CheckFailed` from `kalman_course.checks.harness`"]


def test_unparsable_cells_and_magics_are_not_flags():
    for source in ("def broken(:\n    pass", "%%bash\necho hi", "x = 1?"):
        assert review_flags(_with_extra_cell(source), _release(CH01)) == []


def test_grader_cells_are_skipped_and_nothing_is_modified():
    """Grading restores grader cells, so what a learner put there is not reported twice."""
    nb = _solved(CH01)
    next(c for c in nb.cells if c["id"] == "grader-door_likelihood").source = "import importlib"
    before = copy.deepcopy(nb)
    assert review_flags(nb, _release(CH01)) == []
    assert nb == before
