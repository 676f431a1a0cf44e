"""Execute course notebooks in place and store them in a canonical, deterministic form.

Lecture and solution notebooks are kept executed, with outputs, so that nbval can compare
a fresh run against them. ``kalman-course execute`` is the only way they should be
rebuilt: it runs every cell in a fresh kernel started in the notebook's folder and then
removes everything that would differ between two runs (execution timestamps, the Python
patch version, random cell ids, how printed text was split into pieces).
"""

from __future__ import annotations

import copy
import hashlib
import json
import time
from pathlib import Path

#: The nbformat minor version every stored notebook is written with (4.5 has cell ids).
NBFORMAT_MINOR = 5


class NotebookError(ValueError):
    """A file is not a readable Jupyter notebook (the message says why)."""


class Node(dict):
    """A notebook's JSON object with attribute access (``nb.cells``, ``cell.source``), as
    nbformat's ``NotebookNode`` but without importing nbformat (a second, for its schema)."""

    def __getattr__(self, key):
        try:
            return self[key]
        except KeyError:
            raise AttributeError(key) from None

    def __setattr__(self, key, value):
        self[key] = value


def read_notebook(path: str | Path) -> Node:
    """Read a version-4 notebook for grading: JSON, checked for the structure grading uses.

    Multi-line sources and output texts stored as lists of lines are joined, as nbformat
    does. Any minor version is read, and cell ids and tags are left as they are, whatever
    they are (a list, a number, missing, in ``metadata.id`` as Colab keeps them):
    :mod:`kalman_course.tooling.identify` decides what they say. Raises ``FileNotFoundError`` for a missing file and :class:`NotebookError` for
    anything that is not a version-4 notebook (empty, corrupt JSON, no cell list, ...).
    """
    try:
        nb = json.loads(Path(path).read_text(encoding="utf-8"), object_hook=Node)
    except UnicodeDecodeError:
        raise NotebookError("not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise NotebookError(f"not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(nb, Node) or nb.get("nbformat") != 4:
        raise NotebookError("not a version-4 notebook (no \"nbformat\": 4)")
    if not isinstance(nb.get("cells"), list) or not isinstance(nb.get("metadata", {}), dict):
        raise NotebookError("its cells are not a list")
    nb.setdefault("metadata", Node())
    for i, cell in enumerate(nb.cells):
        if not isinstance(cell, Node) or cell.get("cell_type") not in ("code", "markdown", "raw"):
            raise NotebookError(f"cell {i} is not a code, markdown or raw cell")
        cell["source"] = _joined(cell.get("source", ""), f"cell {i}'s source")
        if not isinstance(cell.setdefault("metadata", Node()), dict):
            raise NotebookError(f"cell {i}'s metadata is not an object")
        if cell.cell_type == "code":
            if not isinstance(cell.setdefault("outputs", []), list):
                raise NotebookError(f"cell {i}'s outputs are not a list")
            for out in cell.outputs:
                if isinstance(out, Node) and "text" in out:
                    out["text"] = _joined(out["text"], f"an output of cell {i}")
    return nb


def _joined(text, what: str) -> str:
    if isinstance(text, list) and all(isinstance(line, str) for line in text):
        return "".join(text)
    if not isinstance(text, str):
        raise NotebookError(f"{what} is not text")
    return text


def stable_cell_id(index: int, source: str) -> str:
    """Return a short deterministic id for a cell that has none yet."""
    digest = hashlib.sha1(f"{index}:{source}".encode()).hexdigest()[:8]
    return f"c{index:02d}-{digest}"


WIDGET_VIEW = "application/vnd.jupyter.widget-view+json"


def normalise(nb):
    """Return a copy of ``nb`` without run-to-run noise.

    Removes per-cell execution timing, the kernel's Python patch version, widget state and
    live widget views,
    gives every cell an id (kept when present), and renumbers execution counts so that
    they only depend on the cell order.
    """
    nb = copy.deepcopy(nb)
    nb.nbformat, nb.nbformat_minor = 4, NBFORMAT_MINOR
    nb.metadata.pop("widgets", None)
    nb.metadata["kernelspec"] = {"display_name": "Python 3", "language": "python", "name": "python3"}
    nb.metadata["language_info"] = {"name": "python"}
    count = 0
    seen: set[str] = set()
    for i, cell in enumerate(nb.cells):
        cell.metadata.pop("execution", None)
        cell.metadata.pop("collapsed", None)
        cell.metadata.pop("scrolled", None)
        cid = cell.get("id")
        if not cid or cid in seen:
            cell["id"] = stable_cell_id(i, cell.source)
        seen.add(cell["id"])
        if cell.cell_type == "code":
            # a live widget's view refers to a model in the kernel that ran it (a random id):
            # outside that session it shows nothing, so it is not stored
            cell.outputs = _coalesce_streams([out for out in cell.outputs
                                              if WIDGET_VIEW not in out.get("data", {})])
            if cell.get("execution_count") is not None or cell.outputs:
                count += 1
                cell.execution_count = count
                for out in cell.outputs:
                    if "execution_count" in out:
                        out["execution_count"] = count
    return nb


def _coalesce_streams(outputs: list) -> list:
    """Merge consecutive stdout (or stderr) pieces: how a print was split is timing noise."""
    merged: list = []
    for out in outputs:
        if (out.get("output_type") == "stream" and merged and merged[-1].get("output_type") == "stream"
                and merged[-1].get("name") == out.get("name")):
            merged[-1]["text"] += out["text"]
        else:
            merged.append(out)
    return merged


def notebook_text(nb) -> str:
    """Return ``nb`` exactly as JupyterLab saves it (nbformat's writer: sorted keys, one-space
    indent, multi-line text as lists of lines, a final newline), so that opening and saving an
    unchanged notebook changes nothing."""
    import nbformat

    text = nbformat.writes(nbformat.from_dict(nb), version=4)
    return text if text.endswith("\n") else text + "\n"


def write_notebook(nb, path: Path) -> None:
    """Write ``nb`` to ``path`` in the canonical layout."""
    Path(path).write_text(notebook_text(nb), encoding="utf-8")


def run_cells(nb, folder: Path, *, timeout: int = 600,
              kernel_name: str = "python3") -> float:
    """Run every cell of ``nb`` (in place, in memory) in a new kernel started in ``folder``.

    Returns the wall time in seconds; a cell that raises raises ``CellExecutionError``.
    """
    from nbclient import NotebookClient

    start = time.perf_counter()
    NotebookClient(nb, timeout=timeout, kernel_name=kernel_name,
                   resources={"metadata": {"path": str(Path(folder).resolve())}},
                   # the kernel's start-up notices (transport warnings) are noise here
                   extra_arguments=["--log-level=ERROR"]).execute()
    return time.perf_counter() - start


def execute_notebook(path: str | Path, *, timeout: int = 600, kernel_name: str = "python3") -> float:
    """Run every cell of the notebook at ``path`` in a new kernel and store the outputs.

    The kernel starts in the notebook's folder. A cell that raises stops the run and
    leaves the file unchanged.

    Returns
    -------
    float
        Wall time of the run in seconds.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"notebook not found: {path}")
    import nbformat

    nb = nbformat.read(path, as_version=4)
    elapsed = run_cells(nb, path.parent, timeout=timeout, kernel_name=kernel_name)
    write_notebook(normalise(nb), path)
    return elapsed
