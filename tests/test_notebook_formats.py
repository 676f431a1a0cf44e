"""Notebooks saved by every editor are graded as JupyterLab's; cell ids cannot mislead grading.

No kernel runs here. Each released exercise and each solution is saved as other editors
save it (``notebook_editors.py``: nbformat 4.0-4.4 without ids, Colab with and without its
tags, VS Code, ids renumbered, sources as one string), read as grading reads it, and must
give the very notebook to run, tamper report and review flags that the same notebook saved
by JupyterLab gives. Then the hostile side: a learner cell carrying a grader's id (before or
after the real grader), ids that are lists, numbers, empty or missing, a grader cell edited
in a notebook without ids, a copy of a grader elsewhere; each is found, named by its place,
and reported, and none crashes grading.
"""

import copy
import functools
import json

import pytest

from kalman_course.tooling.cells import BEGIN_RE, END_RE, STUB_RE
from kalman_course.tooling import grading
from kalman_course.tooling.identify import identify_cells
from kalman_course.tooling.notebooks import read_notebook
from kalman_course.tooling.review import review_flags

from conftest import ROOT, first_line
from notebook_editors import EDITORS, classic, colab_no_tags, own_id

CHAPTERS = sorted(p.name for p in (ROOT / "exercises").glob("[0-9]*.ipynb"))
CH01, CH03 = "01_bayes_rule.ipynb", "03_kalman_filter.ipynb"
#: Editors whose notebooks carry no valid id at all.
WITHOUT_IDS = {"classic_4_0", "classic_4_1", "classic_4_2", "classic_4_3", "classic_4_4", "vscode_4_4",
               "nbformat_4_4"}
GRADER_TAGS = ["grader", "nbval-check-output"]
CLASSIC = classic(4)


@functools.lru_cache(maxsize=None)
def _release() -> dict:
    return grading.load_release(ROOT / "exercises")


def _released(chapter: str):
    return _release()[chapter[:2]]


@functools.lru_cache(maxsize=None)
def _text(folder: str, chapter: str) -> str:
    """The file as JupyterLab saved it; from ``solutions``, as a learner who solved the exercise
    saves it (the solution's region markers gone: they would flag it as a copy)."""
    text = (ROOT / folder / chapter).read_text(encoding="utf-8")
    if folder != "solutions":
        return text
    nb = json.loads(text)
    for cell in nb["cells"]:
        cell["source"] = [line for line in cell["source"]
                          if not any(r.match(line.rstrip("\n")) for r in (BEGIN_RE, STUB_RE, END_RE))]
    return json.dumps(nb, indent=1, ensure_ascii=False) + "\n"


def _json(folder: str, chapter: str) -> dict:
    """The notebook as JupyterLab saved it, as plain JSON."""
    return json.loads(_text(folder, chapter))


def _read(tmp_path, text: str, name: str):
    """``text`` written to a file and read back as grading reads a submission."""
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return read_notebook(path)


def _jupyterlab(tmp_path, nb: dict, chapter: str):
    """``nb`` (edited JSON, ids and all) as a JupyterLab submission (written as it is: nbformat's
    writer would refuse the duplicated ids some tests need)."""
    return _read(tmp_path, json.dumps(nb), f"lab_{chapter}")


def _index(nb: dict, cid: str) -> int:
    return next(i for i, c in enumerate(nb["cells"]) if c.get("id") == cid)


def _code_cell(source: str, cid=None, **metadata) -> dict:
    cell = {"cell_type": "code", "execution_count": None, "metadata": metadata, "outputs": [], "source": source}
    if cid is not None:
        cell["id"] = cid
    return cell


def _graded_form(nb, chapter: str):
    """What grading makes of ``nb``: the cells that run, as (type, source, is a grader), the
    tamper report, the re-added graders and the review flags."""
    release = _released(chapter)
    restored, tampered, readded = grading.restore_graders(nb, release)
    cells = [(c.cell_type, c.source, grading.grader_info(c) is not None) for c in restored.cells]
    ids = [c["id"] for c in restored.cells]
    assert len(ids) == len(set(ids)), "every cell of the notebook that runs has an id of its own"
    return cells, tampered, readded, review_flags(nb, release)


# ---------------------------------------------------------------------------------------
# honest notebooks, whatever saved them
# ---------------------------------------------------------------------------------------

def test_the_converters_write_what_they_claim(tmp_path):
    """Without ids, ids in metadata.id, tags dropped: else the tests below would prove nothing."""
    nb = _json("solutions", CH03)
    for name, editor in EDITORS.items():
        saved = json.loads(editor(nb))
        top_ids = [c.get("id") for c in saved["cells"]]
        if name in WITHOUT_IDS or name.startswith("colab"):
            assert top_ids == [None] * len(top_ids), name
            assert saved["nbformat_minor"] < 5, name
        else:
            assert None not in top_ids, name
    colab = json.loads(colab_no_tags(nb))
    assert all(set(c["metadata"]) <= {"id", "colab", "outputId"} for c in colab["cells"])
    assert "kalman_course" not in colab["metadata"] and colab["nbformat_minor"] == 0
    assert json.loads(EDITORS["renumbered"](nb))["cells"][0]["id"] != nb["cells"][0]["id"]


@pytest.mark.parametrize("folder", ["exercises", "solutions"])
@pytest.mark.parametrize("editor", sorted(EDITORS))
@pytest.mark.parametrize("chapter", CHAPTERS)
def test_a_notebook_saved_by_any_editor_is_graded_as_jupyterlab_s(tmp_path, chapter, editor, folder):
    original = _read(tmp_path, _text(folder, chapter), f"lab_{chapter}")
    saved = _read(tmp_path, EDITORS[editor](_json(folder, chapter)), chapter)
    expected = _graded_form(original, chapter)
    assert expected[1:] == ([], [], []), "the JupyterLab original itself is clean"
    assert _graded_form(saved, chapter) == expected


@pytest.mark.parametrize("editor", sorted(EDITORS))
def test_an_edited_learner_cell_is_compared_with_the_cell_it_was_written_into(tmp_path, editor):
    """Chapter 03's setup cell imports part of the checks: edited, it is still that cell, so
    its released imports are no flag, whatever the editor kept of its id."""
    nb = _json("solutions", CH03)
    setup = nb["cells"][_index(nb, "setup")]
    setup["source"] = ["%matplotlib inline\n", *setup["source"]]
    saved = _read(tmp_path, EDITORS[editor](nb), CH03)
    assert _graded_form(saved, CH03) == _graded_form(_jupyterlab(tmp_path, nb, CH03), CH03)
    assert review_flags(saved, _released(CH03)) == []
    if not identify_cells(saved, _released(CH03)).kept_ids:
        moved = copy.deepcopy(saved)  # the control: the same cell where no released cell can pair with it
        moved.cells.append(moved.cells.pop(1))
        assert review_flags(moved, _released(CH03)), "moved to the end, the setup cell's own flags show"


def _label_in(saved: dict, index: int) -> str:
    """How a cell of a saved notebook is named: by its id (``id`` or Colab's), else its place."""
    cell = saved["cells"][index]
    cid = cell.get("id", cell["metadata"].get("id"))
    return f"cell {cid}" if cid else f"cell {index + 1} (no id{first_line(''.join(cell['source']))})"


@pytest.mark.parametrize("editor", sorted(EDITORS))
def test_a_shortcut_is_flagged_the_same_in_every_editor_s_notebook(tmp_path, editor):
    nb = _json("solutions", CH03)
    update = _index(nb, "update")
    nb["cells"][update]["source"] = "from kalman_course.filters.kf import kf_update"
    text = EDITORS[editor](nb)
    flags = review_flags(_read(tmp_path, text, CH03), _released(CH03))
    assert flags == [f"{_label_in(json.loads(text), update)}: imports `kf_update` from `kalman_course.filters.kf` "
                     "instead of writing it"]


# ---------------------------------------------------------------------------------------
# the chapter of a file in the flat class layout
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, chapter", [("alice__01_bayes_rule.ipynb", "01"), ("12__03_kalman_filter.ipynb", "03"),
                                           ("03_kalman_filter__v2.ipynb", "03"), ("01_bayes_rule.ipynb", "01"),
                                           ("alice__notes.ipynb", "")])
def test_the_chapter_is_read_after_the_learner_s_name(tmp_path, name, chapter):
    nb = _read(tmp_path, CLASSIC(_json("exercises", CH01)), "x.ipynb")
    del nb.metadata["kalman_course"]
    assert grading.chapter_of_notebook(nb, tmp_path / name, _release()) == chapter
    assert grading.learner_of(tmp_path / name, tmp_path) == (name.split("__")[0] if "__" in name else "-")


class _NoKernel:
    """Stands for a kernel session: these tests never start one."""

    def __getattr__(self, name):
        return lambda *args, **kwargs: None


def test_a_flat_layout_notebook_without_ids_or_metadata_is_graded_with_errors_named_by_place(tmp_path, monkeypatch):
    """``learner__01_x.ipynb`` as the classic Notebook saves it, the course metadata gone:
    chapter 01, every grader found, and the errors of cells without a valid id named by place."""
    nb = json.loads(CLASSIC(_json("solutions", CH01)))
    del nb["metadata"]["kalman_course"]
    update = next(i for i, c in enumerate(nb["cells"]) if "def histogram_update" in "".join(c["source"]))
    nb["cells"][update]["id"] = [1, 2]  # a list, as an edit of the JSON leaves it
    path = tmp_path / "alice__01_bayes_rule.ipynb"
    path.write_text(json.dumps(nb), encoding="utf-8")

    def run_graded(restored, **kwargs):
        verdicts = {c["id"]: grading._GraderVerdict(True) for c in restored.cells if grading.grader_info(c)}
        errors = [(c["id"], "NameError: oops") for c in restored.cells
                  if c.cell_type == "code" and "def histogram_update" in c.source]
        return grading.GRADED, verdicts, errors, ""

    monkeypatch.setattr(grading, "_fresh_session", lambda *args, **kwargs: _NoKernel())
    monkeypatch.setattr(grading, "run_graded", run_graded)
    result = grading.grade_notebook(path, _release(), learner="alice")
    assert (result.chapter, result.status, result.points, result.possible) == ("01", grading.GRADED, 8, 8)
    assert (result.tampered, result.readded, result.flags) == ([], [], [])
    note = first_line("".join(nb["cells"][update]["source"]))
    assert result.learner_errors == [f"cell {update + 1} (invalid id{note}): NameError: oops"]


# ---------------------------------------------------------------------------------------
# hostile ids and edits
# ---------------------------------------------------------------------------------------

FORGED = "from kalman_course.filters.kf import kf_update"
IMPORTS = "imports `kf_update` from `kalman_course.filters.kf` instead of writing it"


@pytest.mark.parametrize("where", ["before", "after"])
@pytest.mark.parametrize("with_tags", [False, True])
def test_a_learner_cell_with_a_grader_s_id_is_a_learner_cell_reviewed_and_reported(tmp_path, where, with_tags):
    """The known forgery: a cell that imports the reference, under the id of the grader that
    checks it. It runs as a learner cell, is flagged by its place, and the id is reported."""
    nb = _json("exercises", CH03)
    real = _index(nb, "grader-kf_update")
    metadata = copy.deepcopy(nb["cells"][real]["metadata"]) if with_tags else {}
    forged = real if where == "before" else real + 1
    nb["cells"].insert(forged, _code_cell(FORGED, "grader-kf_update", **metadata))
    real = real + 1 if where == "before" else real
    submission = _jupyterlab(tmp_path, nb, CH03)
    restored, tampered, readded = grading.restore_graders(submission, _released(CH03))
    label = f"cell {forged + 1} (id grader-kf_update, also used by cell {real + 1}{first_line(FORGED)})"
    expected = [f"{label}: a learner cell carried the id of grader cell grader-kf_update "
                "(it ran and was reviewed as a learner cell)"]
    if with_tags:
        expected.insert(0, f"{label}: a learner cell carried grader tags grader, nbval-check-output (removed)")
    assert (tampered, readded) == (expected, [])
    assert restored.cells[real] == _released(CH03).cells[_index(_json("exercises", CH03), "grader-kf_update")]
    assert restored.cells[forged].source == FORGED and grading.grader_info(restored.cells[forged]) is None
    assert restored.cells[forged]["id"] != "grader-kf_update"
    assert review_flags(submission, _released(CH03)) == [f"{label}: {IMPORTS}"]


def test_a_reused_learner_cell_id_never_points_a_flag_at_the_honest_cell(tmp_path):
    nb = _json("solutions", CH03)
    update = _index(nb, "update")
    nb["cells"].insert(update, _code_cell(FORGED, "update"))
    flags = review_flags(_jupyterlab(tmp_path, nb, CH03), _released(CH03))
    assert flags == [f"cell {update + 1} (id update, also used by cell {update + 2}{first_line(FORGED)}): {IMPORTS}"]


@pytest.mark.parametrize("bad", [[1, 2], 7, 3.5, "", None, "has space", "x" * 65, {"id": "grader-kf_update"}, "gone"])
def test_malformed_ids_never_crash_grading_nor_change_it(tmp_path, bad):
    """On a grader cell and on learner cells of an otherwise JupyterLab notebook."""
    nb = _json("solutions", CH03)
    for cid in ("grader-kf_update", "update", "setup"):
        cell = nb["cells"][_index(nb, cid)]
        if bad == "gone":
            del cell["id"]
        else:
            cell["id"] = bad
    original = _read(tmp_path, _text("solutions", CH03), f"lab_{CH03}")
    submission = _read(tmp_path, json.dumps(nb), CH03)
    assert _graded_form(submission, CH03) == _graded_form(original, CH03)
    update = next(i for i, c in enumerate(submission.cells) if c.source.startswith("def kf_update"))
    submission.cells[update].source = FORGED
    what = "no id" if bad in ("", None, "gone") else "invalid id"
    assert review_flags(submission, _released(CH03)) == [f"cell {update + 1} ({what}{first_line(FORGED)}): {IMPORTS}"]


def test_ids_shared_by_many_cells_name_every_other_place(tmp_path):
    nb = _json("solutions", CH03)
    for cid in ("cv", "predict", "gain"):
        nb["cells"][_index(nb, cid)]["id"] = "same"
    submission = _read(tmp_path, json.dumps(nb), CH03)
    labels = identify_cells(submission, _released(CH03)).labels
    notes = [first_line(submission.cells[i].source) for i in (3, 6, 9)]
    assert [labels[i] for i in (3, 6, 9)] == [f"cell 4 (id same, also used by cells 7, 10{notes[0]})",
                                              f"cell 7 (id same, also used by cells 4, 10{notes[1]})",
                                              f"cell 10 (id same, also used by cells 4, 7{notes[2]})"]
    assert _graded_form(submission, CH03)[1:] == ([], [], [])


def _no_ids(folder: str = "solutions", chapter: str = CH03, edit=None):
    """A notebook as the classic Notebook saves it (no ids), after ``edit`` of its cells (by index)."""
    nb = json.loads(CLASSIC(_json(folder, chapter)))
    if edit:
        edit(nb["cells"])
    return nb


def test_an_edited_grader_without_an_id_is_found_by_its_tags_and_reported(tmp_path):
    grader = _index(_json("solutions", CH03), "grader-kf_predict")

    def edit(cells):
        cells[grader]["source"] = 'print("kf_predict: passed")'
    nb = _read(tmp_path, json.dumps(_no_ids(edit=edit)), CH03)
    cells, tampered, readded, flags = _graded_form(nb, CH03)
    note = first_line('print("kf_predict: passed")')
    assert tampered == [f"cell {grader + 1} (no id{note}), grader cell grader-kf_predict: source edited"]
    assert (readded, flags) == ([], [])
    assert cells == _graded_form(_read(tmp_path, _text("solutions", CH03), "lab.ipynb"), CH03)[0]


def test_an_edited_grader_without_id_or_tags_is_readded_and_its_cell_runs_as_the_learner_s(tmp_path):
    """Colab without tags: nothing says which cell the edited grader was, so the release's
    grader is put back after the learner's cell before it, and the edited cell runs as written."""
    nb = _json("solutions", CH03)
    grader = _index(nb, "grader-kf_predict")
    nb["cells"][grader]["source"] = 'print("kf_predict: passed")'
    cells, tampered, readded, flags = _graded_form(_read(tmp_path, colab_no_tags(nb), CH03), CH03)
    assert (tampered, readded, flags) == ([], ["grader-kf_predict"], [])
    assert cells[grader] == ("code", "checks.kf_predict(kf_predict)", True)
    assert cells[grader + 1] == ("code", 'print("kf_predict: passed")', False)


@pytest.mark.parametrize("change, report", [
    (lambda cell: cell["metadata"].update(tags=["nbval-check-output"]), "tags changed (-grader)"),
    (lambda cell: cell["metadata"]["kalman_course"].update(points=20), "grading metadata changed (check or points)"),
    (lambda cell: cell.update(cell_type="markdown", outputs=None), "turned into a markdown cell"),
])
def test_json_edits_of_a_grader_without_an_id_are_reported(tmp_path, change, report):
    grader = _index(_json("solutions", CH03), "grader-kf_gain")

    def edit(cells):
        change(cells[grader])
        if cells[grader]["cell_type"] == "markdown":
            del cells[grader]["outputs"], cells[grader]["execution_count"]
    cells, tampered, readded, _ = _graded_form(_read(tmp_path, json.dumps(_no_ids(edit=edit)), CH03), CH03)
    note = first_line("checks.kf_gain(kf_gain)")
    assert (tampered, readded) == ([f"cell {grader + 1} (no id{note}), grader cell grader-kf_gain: {report}"], [])
    assert cells[grader] == ("code", "checks.kf_gain(kf_gain)", True)


@pytest.mark.parametrize("to", ["top", "end"])
def test_a_copy_of_a_grader_elsewhere_is_a_learner_cell_and_the_real_one_is_the_grader(tmp_path, to):
    """No ids: two cells with the grader's source and tags; the one where the release has the
    grader is taken (the copy at the top would run the check before kf_predict exists)."""
    plain = _no_ids()
    grader = _index(_json("solutions", CH03), "grader-kf_predict")
    copy_at = 2 if to == "top" else len(plain["cells"])

    def edit(cells):
        cells.insert(copy_at, copy.deepcopy(cells[grader]))
    cells, tampered, readded, flags = _graded_form(_read(tmp_path, json.dumps(_no_ids(edit=edit)), CH03), CH03)
    expected = _graded_form(_read(tmp_path, json.dumps(plain), CH03), CH03)[0]
    expected.insert(copy_at, ("code", "checks.kf_predict(kf_predict)", False))
    assert cells == expected
    assert tampered == [f"cell {copy_at + 1} (no id{first_line('checks.kf_predict(kf_predict)')}): "
                        "a learner cell carried grader tags grader, "
                        "nbval-check-output (removed)"]
    assert (readded, flags) == ([], [])


def test_a_renamed_grader_in_a_notebook_that_kept_its_ids_is_still_readded(tmp_path):
    """Where the editor kept the release's ids, a grader under a new id is the learner's copy."""
    nb = _json("solutions", CH03)
    nb["cells"][_index(nb, "grader-kf_gain")]["id"] = "my-cell"
    _, tampered, readded, _ = _graded_form(_jupyterlab(tmp_path, nb, CH03), CH03)
    assert readded == ["grader-kf_gain"]
    assert tampered == ["cell my-cell: a learner cell carried grader tags grader, nbval-check-output (removed)"]


def test_colab_ids_are_understood(tmp_path):
    """``metadata.id`` is an id: equal to the release's, it names the cell like JupyterLab's."""
    nb = _json("solutions", CH03)
    nb["cells"][_index(nb, "update")]["source"] = FORGED
    saved = _read(tmp_path, EDITORS["colab_release_ids"](nb), CH03)
    identified = identify_cells(saved, _released(CH03))
    assert identified.kept_ids and identified.labels[_index(nb, "update")] == "cell update"
    assert review_flags(saved, _released(CH03)) == [f"cell update: {IMPORTS}"]
    own = _read(tmp_path, EDITORS["colab"](nb), CH03)
    assert not identify_cells(own, _released(CH03)).kept_ids
    assert own_id(f"{_index(nb, 'update')}:{FORGED}") in review_flags(own, _released(CH03))[0]
