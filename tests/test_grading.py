"""Grading without a kernel: restoring grader cells, reading nbval reports, the table."""

import copy

import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

from kalman_course import grading


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
    assert tampered == ["grader-f_check"] and readded == []
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


def test_learner_cells_cannot_opt_into_or_out_of_grading():
    sub = _release()
    sub.cells[1].metadata["tags"] = ["nbval-skip", "grader", "nbval-check-output"]
    nb, _, _ = grading.restore_graders(sub, _release())
    assert nb.cells[1].metadata["tags"] == ["nbval-ignore-output"]


def test_exception_summary_finds_the_check_message():
    report = ("Notebook cell execution failed\nCell 3: Cell execution caused an exception\n"
              "\x1b[0;31mCheckFailed\x1b[0m: kf_predict: P_check is wrong. Hint: add Q\n")
    assert grading.exception_summary(report) == "CheckFailed: kf_predict: P_check is wrong. Hint: add Q"
    assert grading.exception_summary("NameError: name 'f' is not defined") == \
        "NameError: name 'f' is not defined"


def test_chapter_from_metadata_or_file_name(tmp_path):
    assert grading.chapter_of_notebook(_release(), tmp_path / "x.ipynb") == "07"
    assert grading.chapter_of_notebook(new_notebook(), tmp_path / "03_kf.ipynb") == "03"
    assert grading.chapter_of_notebook(new_notebook(), tmp_path / "kf.ipynb") == ""


def test_missing_release_folder_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="release folder not found"):
        grading.load_release(tmp_path / "nowhere")


@pytest.mark.parametrize("content, name", [("", "empty.ipynb"), ("{not json", "corrupt.ipynb"),
                                           ("hello", "notes.txt")])
def test_unreadable_files_are_reported_not_raised(tmp_path, content, name):
    path = tmp_path / name
    path.write_text(content)
    result = grading.grade_notebook(path, {"07": _release()})
    assert result.status == grading.NOT_A_NOTEBOOK
    assert path.read_text() == content


def test_table_and_gradebooks(tmp_path):
    ok = grading.NotebookResult("a/01_x.ipynb", "01", checks=[grading.CheckResult("f", "grader-f", 2, 2)])
    bad = grading.NotebookResult("b/01_x.ipynb", "01", tampered=["grader-f"],
                                 checks=[grading.CheckResult("f", "grader-f", 0, 2, "CheckFailed: f: wrong")])
    table = grading.format_table([ok, bad])
    assert "2/2" in table and "0/2" in table and "  f: wrong" in table
    assert "total 2/4 points" in table and "edited: grader-f" in table
    grading.write_csv([ok, bad], tmp_path / "g.csv")
    grading.write_json([ok, bad], tmp_path / "g.json")
    assert "f=0/2" in (tmp_path / "g.csv").read_text()
    assert '"points": 2' in (tmp_path / "g.json").read_text()
