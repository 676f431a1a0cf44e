"""Grading without a kernel: restoring grader cells and reporting tampering, reading notebooks, the table."""

import copy

import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

from kalman_course.tooling import gradebook, grading


def _release():
    cells = [new_markdown_cell("intro"), new_code_cell("def f(x):\n    return x"),
             new_code_cell("checks.f_check(f)"), new_code_cell("plot()")]
    for cid, cell in zip(["intro", "code", "grader-f_check", "plot"], cells):
        cell["id"] = cid
    cells[2].metadata.update(tags=["grader", "nbval-check-output"], kalman_course={"check": "f_check", "points": 2})
    cells[2].outputs = [{"output_type": "stream", "name": "stdout", "text": "f_check: passed\n"}]
    nb = new_notebook(cells=cells)
    nb.metadata["kalman_course"] = {"chapter": "07"}
    return nb


def test_untouched_submission_is_not_reported():
    nb, tampered, readded = grading.restore_graders(_release(), _release())
    assert (tampered, readded) == ([], [])
    assert nb.cells[2].source == "checks.f_check(f)"


def test_edited_grader_is_restored_and_reported():
    sub = _release()
    sub.cells[2].source = 'print("f_check: passed")'
    before = copy.deepcopy(sub)
    nb, tampered, readded = grading.restore_graders(sub, _release())
    assert tampered == ["cell grader-f_check: source edited"] and readded == []
    assert nb.cells[2].source == "checks.f_check(f)"
    assert sub == before, "the submission object itself must not change"


@pytest.mark.parametrize("change_id", [False, True])
def test_deleted_or_renamed_grader_is_readded_in_place(change_id):
    sub = _release()
    if change_id:
        sub.cells[2]["id"] = "mine"
    else:
        del sub.cells[2]
    nb, tampered, readded = grading.restore_graders(sub, _release())
    assert readded == ["grader-f_check"]
    ids = [c["id"] for c in nb.cells]
    assert ids.index("grader-f_check") == ids.index("code") + 1
    graders = [c for c in nb.cells if "nbval-check-output" in c.metadata.get("tags", [])]
    assert [c["id"] for c in graders] == ["grader-f_check"], "a renamed copy must not be graded"


def test_learner_cells_cannot_pose_as_graders():
    sub = _release()
    sub.cells[1].metadata["tags"] = ["nbval-skip", "grader", "nbval-check-output"]
    sub.cells[1].metadata["kalman_course"] = {"check": "f_check", "points": 9}
    nb, tampered, _ = grading.restore_graders(sub, _release())
    assert nb.cells[1].metadata["tags"] == ["nbval-skip"] and "kalman_course" not in nb.cells[1].metadata
    assert tampered == ["cell code: a learner cell carried grader tags grader, nbval-check-output (removed)"]


def _renamed_copy(cell, cid):
    cell = copy.deepcopy(cell)
    cell["id"] = cid
    return cell


def _tamper(change):
    def edit(nb):
        change(nb)
        return nb
    return edit


# what a learner may change in the JSON alone, and the words its report must contain
JSON_EDITS = {
    "points": (_tamper(lambda nb: nb.cells[2].metadata["kalman_course"].update(points=20)), "grading metadata"),
    "skip_tag": (_tamper(lambda nb: nb.cells[2].metadata["tags"].append("nbval-skip")), "tags changed (+nbval-skip)"),
    "tag_removed": (_tamper(lambda nb: nb.cells[2].metadata["tags"].remove("nbval-check-output")),
                    "tags changed (-nbval-check-output)"),
    "fake_output": (_tamper(lambda nb: nb.cells[2].outputs.append(
        {"output_type": "stream", "name": "stdout", "text": "g_check: passed\n"})), "stored output edited"),
    "made_markdown": (_tamper(lambda nb: nb.cells[2].update(cell_type="markdown")), "turned into a markdown cell"),
    "chapter": (_tamper(lambda nb: nb.metadata["kalman_course"].update(chapter="01")), "kalman_course.chapter"),
    "fake_grader": (_tamper(lambda nb: nb.cells.insert(3, _renamed_copy(nb.cells[2], "fake"))),
                    "cell fake: a learner cell carried grader tags"),
}


@pytest.mark.parametrize("name", sorted(JSON_EDITS))
def test_json_edits_are_restored_and_each_reported(name):
    change, words = JSON_EDITS[name]
    nb, tampered, _ = grading.restore_graders(change(_release()), _release())
    assert len(tampered) == 1 and words in tampered[0], tampered
    grader = next(c for c in nb.cells if c.get("id") == "grader-f_check")
    assert grader == _release().cells[2]
    assert nb.metadata["kalman_course"] == _release().metadata["kalman_course"]
    assert [c.get("id") for c in nb.cells if grading.grader_info(c)] == ["grader-f_check"]


@pytest.mark.parametrize("outputs", [
    [], [{"output_type": "error", "ename": "CheckFailed", "evalue": "f_check: wrong", "traceback": []}]])
def test_outputs_a_real_run_stores_are_not_tampering(outputs):
    sub = _release()
    sub.cells[2].outputs = outputs
    sub.cells[2].execution_count = 7
    sub.cells[2].metadata["collapsed"] = True  # JupyterLab's own cell metadata
    assert grading.restore_graders(sub, _release())[1] == []


def test_grader_call_reads_only_the_released_form():
    assert grading.grader_call("checks.kf_update(kf_update)") == ("kf_update", ["kf_update"])
    for bad in ("checks.kf_update(kf_update, x=1)", "print('kf_update: passed')", "c.kf(f)", "checks.f(g())"):
        with pytest.raises(ValueError, match="checks.NAME"):
            grading.grader_call(bad)


def test_chapter_from_metadata_or_file_name(tmp_path):
    assert grading.chapter_of_notebook(_release(), tmp_path / "x.ipynb") == "07"
    assert grading.chapter_of_notebook(new_notebook(), tmp_path / "03_kf.ipynb") == "03"
    assert grading.chapter_of_notebook(new_notebook(), tmp_path / "kf.ipynb") == ""
    edited = _release()
    edited.metadata["kalman_course"]["chapter"] = "7"
    assert grading.chapter_of_notebook(edited, tmp_path / "07_x.ipynb", {"07": None}) == "07"
    assert grading.chapter_of_notebook(edited, tmp_path / "x.ipynb", {"07": None}) == "7"
    assert grading.chapter_of_notebook(_release(), tmp_path / "01_x.ipynb", {"01": None, "07": None}) == "07"


def test_missing_release_folder_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="release folder not found"):
        grading.load_release(tmp_path / "nowhere")


@pytest.mark.parametrize("content, name", [("", "empty.ipynb"), ("{not json", "corrupt.ipynb"),
                                           ("hello", "notes.txt"), ('{"nbformat": 3, "worksheets": []}', "old.ipynb"),
                                           ('{"nbformat": 4, "cells": [{"cell_type": "code", "source": 3}]}',
                                            "bad_cell.ipynb")])
def test_unreadable_files_are_reported_not_raised(tmp_path, content, name):
    path = tmp_path / name
    path.write_text(content)
    result = grading.grade_notebook(path, {"07": _release()})
    assert result.status == grading.NOT_A_NOTEBOOK and result.detail.startswith("cannot read it as a notebook: ")
    assert path.read_text() == content


def test_a_missing_file_is_named_as_missing(tmp_path):
    result = grading.grade_notebook(tmp_path / "07_gone.ipynb", {"07": _release()})
    assert (result.status, result.detail) == (grading.NOT_A_NOTEBOOK, f"no such file: {tmp_path / '07_gone.ipynb'}")


def _write(results, **outputs):
    """Write the gradebooks of ``results`` as one unsigned run of exactly them."""
    run = gradebook.run_record([(r.learner, r.path) for r in results], sandbox="none", seed=1)
    return gradebook.write_gradebooks(results, run, **outputs)


def _feedback(folder):
    return {p.stem: p.read_text() for p in folder.iterdir()}


def test_table_and_gradebooks(tmp_path):
    ok = grading.NotebookResult("a/01_x.ipynb", "01", checks=[grading.CheckResult("f", "grader-f", 2, 2)])
    bad = grading.NotebookResult("b/01_x.ipynb", "01", tampered=["grader-f"],
                                 checks=[grading.CheckResult("f", "grader-f", 0, 2, "CheckFailed: f: wrong")])
    table = gradebook.format_table([ok, bad])
    assert "2/2" in table and "0/2" in table and "  f: wrong" in table
    assert "total 2/4 points" in table and "edited: grader-f" in table
    _write([ok, bad], csv_path=tmp_path / "g.csv", json_path=tmp_path / "g.json")
    assert "f=0/2" in (tmp_path / "g.csv").read_text()
    assert '"points": 2' in (tmp_path / "g.json").read_text()


def test_a_challenge_is_counted_apart_from_the_core(tmp_path):
    core = [grading.CheckResult("f", "grader-f", 2, 2), grading.CheckResult("g", "grader-g", 0, 3, "g: wrong")]
    done = grading.NotebookResult("a/01_x.ipynb", "alice", "01",
                                  checks=core + [grading.CheckResult("h", "grader-h", 4, 4, challenge=True)])
    undone = grading.NotebookResult("b/01_x.ipynb", "bob", "01",
                                    checks=core[:1] + [grading.CheckResult("g", "grader-g", 3, 3),
                                                       grading.CheckResult("h", "grader-h", 0, 4, "h: no", challenge=True)])
    assert (done.points, done.possible, done.challenge_points, done.challenge_possible) == (2, 5, 4, 4)
    assert (undone.points_text, undone.hint) == ("5/5 +0/4", "")  # an undone challenge is no problem
    assert done.hint == "g: wrong"
    table = gradebook.format_table([done, undone])
    assert "2/5 +4/4" in table and "total 7/10 points" in table and "counted apart" in table
    assert "optional challenge done by 1 of 2" in gradebook.format_summary([done, undone])
    _write([done, undone], csv_path=tmp_path / "g.csv", json_path=tmp_path / "g.json", feedback_dir=tmp_path / "fb")
    header, first = (tmp_path / "g.csv").read_text().splitlines()[:2]
    assert "challenge_points,challenge_possible" in header and ",2,5,4,4," in first
    again = gradebook.read_json(tmp_path / "g.json").results
    assert [(r.points_text, [c.challenge for c in r.checks]) for r in again] == [
        ("2/5 +4/4", [False, False, True]), ("5/5 +0/4", [False, False, True])]
    feedback = _feedback(tmp_path / "fb")
    assert "**h** (optional challenge 0/4): not done" in feedback["bob"]
    assert "Optional challenge: 4/4 points" in feedback["alice"]


def test_review_flags_reach_table_summary_and_gradebook(tmp_path):
    flagged = grading.NotebookResult("a/01_x.ipynb", "alice", "01", flags=["cell c: imports `f` from `m`"],
                                     checks=[grading.CheckResult("f", "grader-f", 2, 2)])
    clean = grading.NotebookResult("b/01_x.ipynb", "bob", "01", checks=[grading.CheckResult("f", "grader-f", 2, 2)])
    # every learner's notebook has the same name: the line names the learner and the file
    assert "review: alice (a/01_x.ipynb): cell c: imports `f` from `m`" in gradebook.format_table([flagged, clean])
    assert "flagged for review: 1" in gradebook.format_summary([flagged, clean])
    assert "flagged" not in gradebook.format_summary([clean])
    _write([flagged, clean], csv_path=tmp_path / "g.csv", feedback_dir=tmp_path / "fb")
    assert "cell c: imports `f` from `m`" in (tmp_path / "g.csv").read_text()
    feedback = _feedback(tmp_path / "fb")
    assert "Flagged for review" in feedback["alice"] and "Flagged" not in feedback["bob"]


def test_a_failing_review_never_costs_the_grade(tmp_path, monkeypatch):
    import nbformat

    def broken_review(nb, ref):
        raise RecursionError("deep")

    passed = {"grader-f_check": grading._GraderVerdict(True)}
    monkeypatch.setattr(grading, "review_flags", broken_review)
    class NoKernel:
        def show_notebooks(self, notebooks):
            pass

    monkeypatch.setattr(grading, "_fresh_session", lambda timeout, sandbox, package: NoKernel())
    monkeypatch.setattr(grading, "run_graded", lambda nb, timeout, compare, session, labels: (grading.GRADED, passed, [], ""))
    path = tmp_path / "07_x.ipynb"
    nbformat.write(nbformat.from_dict(_release()), path)
    result = grading.grade_notebook(path, {"07": _release()})
    assert (result.status, result.points) == (grading.GRADED, 2)
    assert result.flags == ["the code review failed (RecursionError); read the notebook by hand"]


@pytest.mark.slow
def test_a_dead_kernel_is_noticed_within_two_seconds(tmp_path):
    import time

    from conftest import ROOT

    release = grading.load_release(ROOT / "exercises")
    nb = grading.read_notebook(ROOT / "exercises" / "01_bayes_rule.ipynb")
    stamp = tmp_path / "died_at"
    first_code = next(i for i, c in enumerate(nb.cells) if c.cell_type == "code")
    nb.cells[first_code].source = (f"import os, time\nopen({str(stamp)!r}, 'w').write(repr(time.time()))\n"
                                   "os._exit(1)")
    result = grading.grade_submission(nb, release, grading.NotebookResult("01_bayes_rule.ipynb"), timeout=60)
    noticed = time.time() - float(stamp.read_text())
    assert result.status == grading.KERNEL_DIED and result.points == 0
    assert noticed < 2.0, f"the dead kernel was noticed after {noticed:.1f} s"


def test_a_function_that_is_not_defined_is_told_as_such():
    from kalman_course.checks.remote import LocalSession

    cells = [new_code_cell("import numpy as np"), new_code_cell("def f(x):\n    return x +"),
             new_code_cell("def g(x):\n    return x"), new_code_cell("del g")]
    for cid, cell in zip(["imports", "code", "other", "gone"], cells):
        cell["id"] = cid
    session = LocalSession({"np": None})
    labels = {"code": "cell code", "other": "cell other"}
    errors = [("code", "SyntaxError: invalid syntax")]
    message = grading._undefined(session, ["f"], cells, errors, labels)
    assert message.startswith("f is not defined: its cell, cell code, raised SyntaxError: invalid syntax. Hint: ")
    assert "shape" not in message
    assert grading._undefined(session, ["g"], cells, errors, labels).startswith(
        "g is not defined when this grader cell runs, although cell other defines it")
    assert "no cell of the notebook defines it" in grading._undefined(session, ["h"], cells, errors, labels)
    assert grading._undefined(LocalSession({"f": len}), ["f"], cells, errors, labels) == ""



def test_grading_yourself_ends_with_the_hint_wrapped_and_the_next_step():
    hint = ("CheckFailed: kf_predict: P is wrong. Hint: " + "the process noise enters through B " * 8).strip()
    mine = grading.NotebookResult("exercises/03_kalman_filter.ipynb", "-", "03",
                                  checks=[grading.CheckResult("kf_gain", "g1", 2, 2),
                                          grading.CheckResult("kf_predict", "g2", 0, 2, hint)])
    table = gradebook.format_table([mine])
    assert "first failing check" in table and "learner" not in table
    lines = table.splitlines()
    assert lines[2].rstrip().endswith("kf_predict") and max(map(len, lines)) <= gradebook.CONSOLE_WIDTH
    assert "03_kalman_filter.ipynb, kf_predict:" in lines and "  P is wrong. Hint: the process" in table
    step = gradebook.next_step([mine], all_hints=False)
    assert step.startswith("next: in exercises/03_kalman_filter.ipynb, fix kf_predict")
    assert "--all-hints" in step and max(map(len, step.splitlines())) <= gradebook.CONSOLE_WIDTH
    done = grading.NotebookResult("exercises/03_kalman_filter.ipynb", "-", "03",
                                  checks=[grading.CheckResult("kf_gain", "g1", 2, 2)])
    assert gradebook.next_step([done], all_hints=False) == "next: every core check passes"
    # a class keeps the hint in its table and gets the class statistics instead
    class_table = gradebook.format_table([grading.NotebookResult("a/03.ipynb", "alice", "03", checks=mine.checks)])
    assert "first hint" in class_table and "kf_predict: P is wrong" in class_table
