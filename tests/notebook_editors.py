"""How editors other than JupyterLab save a notebook: converters for the tests.

Each converter takes a notebook as JupyterLab saves it (nbformat 4.5, every cell with its
``id``), read as plain JSON, and returns the text another editor saves for the same cells.
They write the JSON themselves, from the nbformat schemas and from what these editors are
known to write, rather than through nbformat: its writer keeps the ``id`` of a cell in a
notebook marked 4.4, so it cannot stand for an editor that never had ids (one converter
uses it anyway, as the tool a learner might run).

- ``classic_4_N``: the classic Notebook before nbformat 4.5 (no ids; ``collapsed`` on
  code cells; the full ``language_info``);
- ``colab`` and ``colab_no_tags``: Google Colab (``nbformat_minor`` 0, its own ids in
  ``metadata.id``, a ``colab`` block; the second keeps no tags, no other cell metadata
  and no course metadata in the notebook's);
- ``colab_release_ids``: Colab keeping the release's ids as its own;
- ``vscode_4_5`` and ``vscode_4_4``: VS Code (``metadata.vscode``, the interpreter's
  ``language_info``, keys in its order; 4.4 without ids);
- ``renumbered``: nbformat 4.5 with a new id on every cell (an editor, or a tool, that
  gives its own);
- ``one_string``: every source and output text one string instead of a list of lines;
- ``nbformat_4_4``: nbformat's own writer with ``nbformat_minor`` 4 and the ids deleted.
"""

from __future__ import annotations

import base64
import copy
import hashlib
import json
from collections.abc import Callable

#: The full ``language_info`` that a Python kernel reports (the classic Notebook and VS Code store it).
LANGUAGE_INFO = {"codemirror_mode": {"name": "ipython", "version": 3}, "file_extension": ".py",
                 "mimetype": "text/x-python", "name": "python", "nbconvert_exporter": "python",
                 "pygments_lexer": "ipython3", "version": "3.11.4"}


def lines(text) -> list[str]:
    """``text`` as nbformat stores it on disk: a list of lines, each with its newline."""
    if isinstance(text, list):
        return text
    return text.splitlines(keepends=True)


def joined(text) -> str:
    return "".join(text) if isinstance(text, list) else text


def own_id(seed: str) -> str:
    """A 12-character id of the kind Colab gives (letters, digits, ``-`` and ``_``), fixed by ``seed``."""
    return base64.urlsafe_b64encode(hashlib.sha1(seed.encode()).digest()[:9]).decode()


def _without_ids(nb: dict, minor: int) -> dict:
    nb = copy.deepcopy(nb)
    nb["nbformat_minor"] = minor
    for cell in nb["cells"]:
        cell.pop("id", None)
        if minor < 1:
            cell.pop("attachments", None)  # 4.1 introduced attachments
    return nb


def _dump(nb: dict, *, sort_keys: bool = True, indent: int = 1) -> str:
    return json.dumps(nb, sort_keys=sort_keys, indent=indent, ensure_ascii=False) + "\n"


def classic(minor: int) -> Callable[[dict], str]:
    """The classic Notebook saving as nbformat 4.``minor``."""
    def save(nb: dict) -> str:
        nb = _without_ids(nb, minor)
        nb["metadata"]["language_info"] = dict(LANGUAGE_INFO)
        for cell in nb["cells"]:
            if cell["cell_type"] == "code":
                cell["metadata"].setdefault("collapsed", False)
        return _dump(nb)
    save.__name__ = f"classic_4_{minor}"
    return save


def _colab(nb: dict, *, keep_metadata: bool, release_ids: bool) -> str:
    out = {"nbformat": 4, "nbformat_minor": 0,
           "metadata": {"colab": {"provenance": [], "toc_visible": True},
                        "kernelspec": {"name": "python3", "display_name": "Python 3"},
                        "language_info": {"name": "python"}},
           "cells": []}
    if keep_metadata and "kalman_course" in nb["metadata"]:
        out["metadata"]["kalman_course"] = copy.deepcopy(nb["metadata"]["kalman_course"])
    for k, cell in enumerate(nb["cells"]):
        kept = copy.deepcopy(cell["metadata"]) if keep_metadata else {}
        meta = {"id": cell["id"] if release_ids else own_id(f"{k}:{joined(cell['source'])}"), **kept}
        new = {"cell_type": cell["cell_type"], "source": lines(cell["source"]), "metadata": meta}
        if cell["cell_type"] == "code":
            meta["colab"] = {"base_uri": "https://localhost:8080/"}
            new["execution_count"] = cell.get("execution_count")
            new["outputs"] = copy.deepcopy(cell.get("outputs", []))
            if new["outputs"]:
                meta["outputId"] = own_id(f"out{k}")
        out["cells"].append(new)
    return json.dumps(out, indent=2, ensure_ascii=False)


def colab(nb: dict) -> str:
    """Colab keeping the cells' tags and metadata."""
    return _colab(nb, keep_metadata=True, release_ids=False)


def colab_no_tags(nb: dict) -> str:
    """Colab dropping every cell's tags and metadata but its own, and the course's notebook metadata."""
    return _colab(nb, keep_metadata=False, release_ids=False)


def colab_release_ids(nb: dict) -> str:
    """Colab that took the release's ids as its own ``metadata.id``."""
    return _colab(nb, keep_metadata=True, release_ids=True)


def _vscode(nb: dict, minor: int) -> str:
    nb = copy.deepcopy(nb) if minor >= 5 else _without_ids(nb, minor)
    nb["nbformat_minor"] = minor
    nb["metadata"]["language_info"] = dict(LANGUAGE_INFO)
    nb["metadata"]["kernelspec"] = {"display_name": ".venv", "language": "python", "name": "python3"}
    nb["metadata"]["vscode"] = {"interpreter": {"hash": hashlib.sha256(b"venv").hexdigest()}}
    for cell in nb["cells"]:
        if cell["cell_type"] == "code":
            cell["metadata"]["vscode"] = {"languageId": "python"}
    # VS Code writes the notebook's keys in its own order, cells first
    ordered = {key: nb[key] for key in ("cells", "metadata", "nbformat", "nbformat_minor")}
    return _dump(ordered, sort_keys=False)


def vscode_4_5(nb: dict) -> str:
    """VS Code on a 4.5 notebook (it keeps the ids)."""
    return _vscode(nb, 5)


def vscode_4_4(nb: dict) -> str:
    """VS Code on a notebook that came as 4.4 (no ids)."""
    return _vscode(nb, 4)


def renumbered(nb: dict) -> str:
    """nbformat 4.5 with a new id on every cell."""
    nb = copy.deepcopy(nb)
    for k, cell in enumerate(nb["cells"]):
        cell["id"] = own_id(f"new {k}")
    return _dump(nb)


def one_string(nb: dict) -> str:
    """Every source and output text as one string (nbformat allows both), ids kept."""
    nb = copy.deepcopy(nb)
    for cell in nb["cells"]:
        cell["source"] = joined(cell["source"])
        for out in cell.get("outputs", []):
            if "text" in out:
                out["text"] = joined(out["text"])
    return _dump(nb)


def nbformat_4_4(nb: dict) -> str:
    """nbformat's writer on the notebook marked 4.4, its ids deleted first."""
    import nbformat

    node = nbformat.from_dict(_without_ids(nb, 4))
    return nbformat.writes(node, version=4)


#: Every editor's way of saving, by name.
EDITORS: dict[str, Callable[[dict], str]] = {
    **{f"classic_4_{minor}": classic(minor) for minor in range(5)},
    "colab": colab, "colab_no_tags": colab_no_tags, "colab_release_ids": colab_release_ids,
    "vscode_4_5": vscode_4_5, "vscode_4_4": vscode_4_4, "renumbered": renumbered, "one_string": one_string,
    "nbformat_4_4": nbformat_4_4,
}
