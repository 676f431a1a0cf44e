"""Stored notebooks are canonical: what `kalman-course execute` removes and keeps."""

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook, new_output

from kalman_course.tooling.notebooks import normalise, notebook_text

from conftest import ROOT


def _executed():
    cells = [new_markdown_cell("# title"), new_code_cell("print('a'); print('b')"), new_code_cell("x = 1")]
    cells[1].execution_count, cells[2].execution_count = 7, 9
    cells[1].metadata["execution"] = {"iopub.execute_input": "2026-11-23T11:00:00Z"}
    cells[1].outputs = [new_output("stream", name="stdout", text="a\n"),
                        new_output("stream", name="stdout", text="b\n"),
                        new_output("stream", name="stderr", text="w\n")]
    nb = new_notebook(cells=cells)
    nb.metadata["language_info"] = {"name": "python", "version": "3.11.7"}
    for c in nb.cells:
        del c["id"]
    return nb


def test_normalise_removes_run_to_run_noise():
    nb = normalise(_executed())
    assert "execution" not in nb.cells[1].metadata
    assert nb.metadata["language_info"] == {"name": "python"}
    assert [c.get("execution_count") for c in nb.cells[1:]] == [1, 2]
    assert [o["text"] for o in nb.cells[1].outputs] == ["a\nb\n", "w\n"]
    ids = [c["id"] for c in nb.cells]
    assert len(set(ids)) == 3
    nbformat.validate(nb)


def test_normalise_is_deterministic_and_idempotent():
    once = notebook_text(normalise(_executed()))
    assert once == notebook_text(normalise(_executed()))
    assert once == notebook_text(normalise(nbformat.reads(once, as_version=4)))


def test_normalise_drops_live_widget_views_and_keeps_figures():
    cell = new_code_cell("explorer")
    cell.execution_count = 3
    view = {"application/vnd.jupyter.widget-view+json": {"model_id": "5f0c9e", "version_major": 2},
            "text/plain": "VBox(children=(FloatLogSlider(value=0.5),))"}
    figure = {"image/png": "iVBORw0KGgo=", "text/plain": "<Figure>"}
    cell.outputs = [new_output("display_data", data=view), new_output("display_data", data=figure)]
    nb = normalise(new_notebook(cells=[cell]))
    assert [o["data"] for o in nb.cells[0].outputs] == [figure]


@pytest.mark.parametrize("path", sorted((ROOT / "notebooks").glob("*.ipynb")) + sorted((ROOT / "solutions").glob("*.ipynb"))
                         + sorted((ROOT / "exercises").glob("*.ipynb")), ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_saving_an_unchanged_notebook_changes_nothing(path):
    """What JupyterLab does on save (the server's nbformat.write of what nbformat.read gave)
    reproduces the stored file byte for byte, so an untouched notebook never shows a diff."""
    import io

    saved = io.StringIO()
    nbformat.write(nbformat.read(path, as_version=4), saved)
    assert saved.getvalue() == path.read_text(encoding="utf-8")
