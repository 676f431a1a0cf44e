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


#: What a notebook file must be, as the errors say it.
NOTEBOOK = "a Jupyter notebook (JSON, nbformat 4)"


class InputError(ValueError):
    """A file or folder given to a command cannot be used: it is missing or of the other kind
    (a file for a folder), unreadable, not UTF-8, empty, or not what it should be.

    ``path`` names it, ``problem`` says what is wrong and ``expected`` what it should have been.
    The command line (:func:`kalman_course.tooling.cli.main`) prints it as one error line and
    exits with status 2.
    """

    template = "{path}: {problem}; expected {expected}"

    def __init__(self, path, problem: str, expected: str):
        self.path, self.problem, self.expected = str(path), problem, expected
        super().__init__(self.template.format(path=path, problem=problem, expected=expected))


class NotebookError(InputError):
    """A file is not a readable Jupyter notebook (the message names it and says why)."""

    def __init__(self, path, problem: str, expected: str = NOTEBOOK):
        super().__init__(path, problem, expected)


def read_text(path: str | Path, expected: str, error: type[InputError] = InputError) -> str:
    """The UTF-8 text of the file at ``path``.

    Raises ``error`` (an :class:`InputError`) naming the file and ``expected`` when it is
    missing, a folder, unreadable, empty (or only blanks) or not UTF-8 text.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise error(path, "no such file", expected) from None
    except IsADirectoryError:
        raise error(path, "a folder, not a file", expected) from None
    except NotADirectoryError:
        raise error(path, f"no such file ({blocking_file(path)} is a file, not a folder)", expected) from None
    except PermissionError:
        raise error(path, "cannot be read (permission denied)", expected) from None
    except OSError as exc:
        raise error(path, f"cannot be read ({exc.strerror or exc})", expected) from None
    if not data.strip():
        raise error(path, "an empty file", expected)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(path, f"not UTF-8 text (byte {exc.start} is not UTF-8)", expected) from None


def json_problem(exc: json.JSONDecodeError) -> str:
    """What a JSON parse error says about the file: cut short, or where it is not JSON."""
    if exc.pos >= len(exc.doc.rstrip()) or exc.msg.startswith("Unterminated string"):
        end = exc.doc.rstrip().count("\n") + 1
        return f"not JSON: it stops at line {end} before the JSON ends (cut short?)"
    return f"not JSON ({exc.msg}: line {exc.lineno}, column {exc.colno})"


def blocking_file(path: str | Path) -> Path | None:
    """The file that stands where a folder on the way to ``path`` should be (``a`` of a
    missing ``a/b/c`` when ``a`` is a file), or None."""
    for parent in Path(path).parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def require_folder(path: str | Path, expected: str) -> Path:
    """``path`` as a Path when it is an existing folder; else :class:`InputError` naming it."""
    path = Path(path)
    if not path.is_dir():
        raise InputError(path, "a file, not a folder" if path.exists() else "no such folder", expected)
    return path


def require_output(path: str | Path, expected: str, *, folder: bool) -> Path:
    """``path`` as a Path when a command may make it or write into it (a folder when ``folder``,
    else a file): :class:`InputError` naming it when it exists as the other kind, or when a
    file stands where one of its parent folders would be made."""
    path = Path(path)
    if path.exists() and path.is_dir() != folder:
        raise InputError(path, "a file, not a folder" if folder else "a folder, not a file", expected)
    blocked = None if path.exists() else blocking_file(path)
    if blocked is not None:
        raise InputError(path, f"{blocked} is a file, not a folder", expected)
    return path


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
    :mod:`kalman_course.tooling.identify` decides what they say. Raises
    :class:`NotebookError` naming the file for anything that is not a version-4 notebook
    (missing, a folder, unreadable, not UTF-8, empty, corrupt or cut-short JSON, another
    nbformat, no cell list, a cell without a source, ...).
    """
    return _checked(_parsed(read_text(path, NOTEBOOK, NotebookError), path), path)


def load_notebook(path: str | Path):
    """Read a version-4 notebook as nbformat reads it (a ``NotebookNode``), for the commands
    that run, build or export one: whatever :func:`read_notebook` refuses, and whatever else
    nbformat's schema refuses, is a :class:`NotebookError` naming the file."""
    from nbformat import reader

    text = read_text(path, NOTEBOOK, NotebookError)
    _checked(_parsed(text, path), path)
    nb = reader.reads(text)
    problem = _schema_problem(nb)
    if problem:
        raise NotebookError(path, problem)
    return nb


def _parsed(text: str, path) -> Node:
    try:
        return json.loads(text, object_hook=Node)
    except json.JSONDecodeError as exc:
        raise NotebookError(path, json_problem(exc)) from None


def _kind(value) -> str:
    return {dict: "an object", Node: "an object", list: "a list", str: "a string"}.get(type(value), "a number")


def _checked(nb, path) -> Node:
    """``nb`` (parsed JSON) with its sources and output texts joined; :class:`NotebookError`
    naming ``path`` if it is not a version-4 notebook."""
    if not isinstance(nb, Node) or "nbformat" not in nb:
        raise NotebookError(path, f"JSON, but not a notebook ({_kind(nb)} without \"nbformat\")")
    if nb["nbformat"] != 4:
        raise NotebookError(path, f"a notebook of nbformat {nb['nbformat']!r}, not 4 (JupyterLab converts it "
                                  "when it opens and saves it)")
    if not isinstance(nb.get("cells"), list):
        raise NotebookError(path, "a notebook without a list of cells (\"cells\")")
    if not isinstance(nb.setdefault("metadata", Node()), dict):
        raise NotebookError(path, "its metadata is not an object")
    for i, cell in enumerate(nb.cells, 1):
        if not isinstance(cell, Node) or cell.get("cell_type") not in ("code", "markdown", "raw"):
            raise NotebookError(path, f"cell {i} is not a code, markdown or raw cell")
        if "source" not in cell:
            raise NotebookError(path, f"cell {i} has no source")
        cell["source"] = _joined(cell["source"], f"cell {i}'s source", path)
        if not isinstance(cell.setdefault("metadata", Node()), dict):
            raise NotebookError(path, f"cell {i}'s metadata is not an object")
        if cell.cell_type == "code":
            if not isinstance(cell.setdefault("outputs", []), list):
                raise NotebookError(path, f"cell {i}'s outputs are not a list")
            for out in cell.outputs:
                if isinstance(out, Node) and "text" in out:
                    out["text"] = _joined(out["text"], f"an output of cell {i}", path)
    return nb


def _schema_problem(nb) -> str:
    """What nbformat's schema refuses in ``nb`` ('' if nothing), where it is and why, briefly."""
    import warnings

    import nbformat

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a cell without an id: normalise gives it one
        try:
            nbformat.validate(nb)
        except nbformat.ValidationError as exc:
            message = " ".join(str(getattr(exc, "message", exc)).split())
            message = message if len(message) <= 160 else message[:157] + "..."
            return f"not a valid notebook: {_schema_place(getattr(exc, 'absolute_path', []))}: {message}"
    return ""


def _schema_place(keys) -> str:
    """``cell 3, output 1, name`` for the schema path ``cells, 2, outputs, 0, name``."""
    keys, words = list(keys), []
    while keys:
        key = keys.pop(0)
        if key in ("cells", "outputs") and keys and isinstance(keys[0], int):
            words.append(f"{key[:-1]} {keys.pop(0) + 1}")  # cells → cell, outputs → output
        else:
            words.append(str(key))
    return ", ".join(words) or "the notebook"


def _joined(text, what: str, path) -> str:
    if isinstance(text, list) and all(isinstance(line, str) for line in text):
        return "".join(text)
    if not isinstance(text, str):
        raise NotebookError(path, f"{what} is not text")
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
    leaves the file unchanged; a file that is not a notebook (:func:`load_notebook`) is not
    run and not changed.

    Returns
    -------
    float
        Wall time of the run in seconds.
    """
    path = Path(path)
    nb = load_notebook(path)
    elapsed = run_cells(nb, path.parent, timeout=timeout, kernel_name=kernel_name)
    write_notebook(normalise(nb), path)
    return elapsed
