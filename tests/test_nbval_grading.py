"""What ``pytest --nbval exercises/NN.ipynb`` tells a learner, in the four states a learner's
file can be in: released (never run), fixed but never run, fixed, run and saved, and saved
with a grader cell that was run before the fix and not after.

The exercise ships without outputs, so nbval runs each cell and compares nothing: exactly
the grader cells fail on the released file (their checks raise) and nothing fails once the
code is right. After a save, nbval compares the grader cells' stored outputs (the learner's
own cells are tagged ``nbval-ignore-output``).
"""

import re
import subprocess
import sys

import nbformat
import pytest

from kalman_course.tooling import authoring

from conftest import ROOT

pytestmark = pytest.mark.slow

CHAPTER = "02_gaussians.ipynb"  # the quickest notebook; the mechanism is the same in every chapter


def _code_index(nb) -> dict[str, int]:
    """Cell id -> nbval's item number (``Cell N`` counts code cells only)."""
    return {c["id"]: n for n, c in enumerate(c for c in nb.cells if c.cell_type == "code")}


def _learner_states(folder):
    """Write the four states of the learner's file; return {state: (path, notebook)}."""
    released = nbformat.read(ROOT / "exercises" / CHAPTER, as_version=4)
    solution = nbformat.read(ROOT / "solutions" / CHAPTER, as_version=4)
    fixed_code = {c["id"]: c.source for c in authoring.render(solution, set()).cells}
    stored = {c["id"]: c for c in solution.cells if c.cell_type == "code"}

    fixed = nbformat.from_dict(released)  # a deep copy
    for cell in fixed.cells:
        if cell.cell_type == "code":
            cell.source = fixed_code[cell["id"]]
    saved = nbformat.from_dict(fixed)
    for cell in saved.cells:  # what a run in JupyterLab stores: the reference's own outputs
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = stored[cell["id"]].outputs, stored[cell["id"]].execution_count
    stale = nbformat.from_dict(saved)
    first_grader = next(c for c in stale.cells if authoring.grader_info(c))
    first_grader.outputs = [nbformat.v4.new_output("error", ename="CheckFailed", evalue="not yet",
                                                   traceback=["CheckFailed: not yet"])]
    states = {}
    for name, nb in [("released", released), ("fixed", fixed), ("saved", saved), ("stale", stale)]:
        path = folder / f"{name}_{CHAPTER}"
        nbformat.write(nb, path)
        states[name] = (path, nb)
    return states, first_grader["id"]


@pytest.fixture(scope="module")
def nbval_outcomes(tmp_path_factory):
    folder = tmp_path_factory.mktemp("learner")
    states, stale_cell = _learner_states(folder)
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-rA", "-p", "no:cacheprovider", "-o", "addopts=",
                          "--nbval", "--nbval-current-env", *(str(p) for p, _ in states.values())],
                         cwd=folder, capture_output=True, text=True, timeout=600)
    outcomes = {name: {} for name in states}
    for line in run.stdout.splitlines():
        m = re.match(r"^(PASSED|FAILED|ERROR) (\w+)_" + re.escape(CHAPTER) + r"::Cell (\d+)", line)
        if m:
            outcomes[m[2]][int(m[3])] = m[1]
    return states, stale_cell, outcomes, run.stdout[-3000:]


def test_the_released_exercise_fails_exactly_its_grader_cells(nbval_outcomes):
    states, _, outcomes, log = nbval_outcomes
    nb = states["released"][1]
    index = _code_index(nb)
    graders = {index[c["id"]] for c in nb.cells if authoring.grader_info(c)}
    assert len(outcomes["released"]) == len(index), log
    assert {n for n, o in outcomes["released"].items() if o != "PASSED"} == graders, log


@pytest.mark.parametrize("state", ["fixed", "saved"])
def test_a_correct_notebook_passes_whether_run_or_not(nbval_outcomes, state):
    states, _, outcomes, log = nbval_outcomes
    assert len(outcomes[state]) == len(_code_index(states[state][1])), log
    assert set(outcomes[state].values()) == {"PASSED"}, log


def test_a_grader_cell_saved_before_the_fix_is_reported(nbval_outcomes):
    states, stale_cell, outcomes, log = nbval_outcomes
    index = _code_index(states["stale"][1])
    assert {n for n, o in outcomes["stale"].items() if o != "PASSED"} == {index[stale_cell]}, log
