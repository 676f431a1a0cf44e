"""Which cell of a submitted notebook is which cell of its released exercise.

JupyterLab saves nbformat 4.5, in which every cell keeps the ``id`` it was released with,
so there the ids name the cells. Other editors save what they save: the classic Notebook
before nbformat 4.5, and most other editors, no ids at all; Google Colab ids of its own in
the cell's ``metadata.id`` (with ``nbformat_minor`` 0), and perhaps no tags; an editor may
give every cell a new id; and an edit of the JSON gives any id to any cell (a list, a
number, the id of a grader cell on a learner's cell). An id is therefore evidence, and only
when it can be:

- a cell's id is its ``id`` (its ``metadata.id`` if it has no ``id``) when that is a valid
  nbformat id, 1 to 64 letters, digits, ``-`` or ``_``; anything else counts as no id;
- the ids are *kept* when some cell's id is a released cell's id (the editor kept the
  release's ids); otherwise they are the editor's own and say nothing about the release;
- each released grader cell is found in exactly one submission cell, the best candidate,
  ranked: the same kept id together with the released source or grading metadata; the
  released source; the grading metadata naming the same check; the same kept id alone (a
  grader rewritten where it stood). A cell that kept another id is no candidate. Among
  equal candidates, the one between the released cells around the grader wins, then the
  first after the previous grader (release order);
- every other cell is the learner's, whatever id it carries, and is paired with the
  released cell it was written into when there is one (by its kept id, else by aligning
  the two notebooks on their cells' sources), which the review compares it with.

People read cells by name: a cell is named by its id when that is valid and unique in the
notebook (``cell update``), else by its place in the file, every cell counted from 1, and
its first line (``cell 7 (no id; first line "def kf_update(...):")``, ``cell 7 (invalid id;
...)``, ``cell 7 (id update, also used by cell 12; first line "...")``).
"""

from __future__ import annotations

import difflib
import re
from collections import Counter
from dataclasses import dataclass

from kalman_course.tooling.cells import grader_info

__all__ = ["Identified", "cell_id", "cell_metadata", "cell_tags", "identify_cells", "same_code"]

_VALID_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")
#: The weight of pairing two cells by their kept id (a pairing by place weighs 1 to 2).
_BY_ID = 10.0
#: Sources are compared on their first lines only, and only while there are this few pairs to
#: compare (beyond, cells are paired by ids and places alone): a hostile notebook of a
#: million cells or lines costs no more than a few released notebooks.
_SIMILAR_LINES, _SIMILAR_PAIRS = 200, 20_000


def cell_metadata(cell) -> dict:
    """The cell's metadata, or an empty one when it is not an object."""
    meta = cell.get("metadata")
    return meta if isinstance(meta, dict) else {}


def cell_tags(cell) -> list[str]:
    """The cell's tags that are text (none when ``tags`` is not a list)."""
    found = cell_metadata(cell).get("tags")
    return [t for t in found if isinstance(t, str)] if isinstance(found, list) else []


def grading_metadata(cell) -> dict | None:
    """The cell's ``kalman_course`` metadata when it is an object, else None."""
    meta = cell_metadata(cell).get("kalman_course")
    return meta if isinstance(meta, dict) else None


def _raw_id(cell):
    return cell["id"] if "id" in cell else cell_metadata(cell).get("id")


def cell_id(cell) -> str | None:
    """The cell's id, nbformat's ``id`` or Colab's ``metadata.id``; None unless it is a valid id."""
    raw = _raw_id(cell)
    return raw if isinstance(raw, str) and _VALID_ID.fullmatch(raw) else None


def _source(cell) -> str:
    source = cell.get("source", "")
    if isinstance(source, list):  # as stored on disk, before a reader joins it
        source = "".join(s for s in source if isinstance(s, str))
    return source if isinstance(source, str) else ""


def _code_lines(source: str) -> list[str]:
    """``source`` as lines without what editors change when they save: line endings,
    trailing blanks, blank lines at either end."""
    lines = [line.rstrip() for line in source.replace("\r\n", "\n").replace("\r", "\n").split("\n")]
    while lines and not lines[-1]:
        lines.pop()
    while lines and not lines[0]:
        lines.pop(0)
    return lines


def same_code(a: str, b: str) -> bool:
    """Whether two cell sources are the same code, whichever editor saved each."""
    return _code_lines(a) == _code_lines(b)


@dataclass
class Identified:
    """What each cell of one submission is, by its index in ``submission.cells``.

    Attributes
    ----------
    labels : list of str
        How to name each cell to a person (see the module docstring).
    ids : list of str or None
        Each cell's valid id.
    run_ids : list of str
        A unique valid id for each cell in the notebook that runs: a grader's is the
        release's, a learner cell keeps its own when it is unique and no grader's.
    graders : dict of int to int
        Index of each cell taken as a grader -> index of that grader in ``release.cells``.
    originals : dict of int to int
        Index of a learner cell -> index of the released cell it was written into.
    kept_ids : bool
        Whether the editor kept the release's ids.
    dropped_tags, dropped_grading : bool
        Whether no cell has tags, or ``kalman_course`` metadata: the editor dropped them on
        every cell, which an honest learner cannot help.
    """

    labels: list[str]
    ids: list[str | None]
    run_ids: list[str]
    graders: dict[int, int]
    originals: dict[int, int]
    kept_ids: bool
    dropped_tags: bool
    dropped_grading: bool

    def release_index(self, i: int) -> int | None:
        """The released cell that submission cell ``i`` is, if any."""
        return self.graders.get(i, self.originals.get(i))

    def label_of_run_id(self) -> dict[str, str]:
        """Run id -> the label of the cell that carries it in the notebook that runs."""
        return dict(zip(self.run_ids, self.labels))


def _is_grader(ref) -> bool:
    return ref.get("cell_type") == "code" and grader_info(ref) is not None


def _grader_rank(cell, cid: str | None, code: list[str], ref, ref_code: list[str], kept: bool) -> tuple | None:
    """How well ``cell`` (its code lines ``code``) matches the released grader ``ref``
    (greater is better), or None if it cannot be that grader."""
    same_id = kept and cid == ref.get("id")
    if kept and cid is not None and not same_id:
        return None  # it kept another id: it is that cell, or a cell the learner added
    same_source = code == ref_code
    meta = grading_metadata(cell)
    same_check = meta is not None and meta.get("check") == ref.metadata["kalman_course"]["check"]
    if not (same_id or same_source or same_check):
        return None
    return same_id and (same_source or same_check), same_source, same_check, same_id, cell.get("cell_type") == "code"


def _similarity(a: list[str], b: list[str]) -> float:
    # the first lines say which cell it is; a cell of a million lines must not cost a million
    return difflib.SequenceMatcher(None, a[:_SIMILAR_LINES], b[:_SIMILAR_LINES], autojunk=False).ratio()


def _monotone_pairs(n: int, m: int, weight) -> list[tuple[int, int]]:
    """The pairs (r, i), increasing in both, of greatest total ``weight(r, i)`` (None: no pair)."""
    took = [bytearray(m + 1) for _ in range(n + 1)]  # took[r][i]: the best of r x i pairs r-1 with i-1
    best_above = [0.0] * (m + 1)  # the best total of the first r released cells, row by row
    came_from_above = [bytearray(m + 1) for _ in range(n + 1)]
    for r in range(n):
        row = [0.0] * (m + 1)
        for i in range(m):
            up, left = best_above[i + 1], row[i]
            w = weight(r, i)
            if w is not None and best_above[i] + w > max(up, left):
                row[i + 1], took[r + 1][i + 1] = best_above[i] + w, 1
            else:
                row[i + 1] = max(up, left)
                came_from_above[r + 1][i + 1] = up >= left
        best_above = row
    pairs, r, i = [], n, m
    while r and i:
        if took[r][i]:
            pairs.append((r - 1, i - 1))
            r, i = r - 1, i - 1
        elif came_from_above[r][i]:
            r -= 1
        else:
            i -= 1
    return pairs[::-1]


def _learner_originals(cells, ids, code, release, release_code, kept: bool, candidates: set[int]) -> dict[int, int]:
    """Pair learner cells with the released learner cells they were written into (the
    cells that could be graders stay out: the review reads them as they are)."""
    rel = [r for r, ref in enumerate(release.cells) if not _is_grader(ref)]
    sub = [i for i in range(len(cells)) if i not in candidates]
    compare = len(rel) * len(sub) <= _SIMILAR_PAIRS  # else by ids and places alone

    def weight(a: int, b: int) -> float | None:
        r, i = rel[a], sub[b]
        if release.cells[r].get("cell_type") != cells[i].get("cell_type"):
            return None
        if kept and ids[i] is not None and ids[i] != release.cells[r].get("id"):
            return None  # a kept id is the cell it names, or no released cell at all
        similarity = _similarity(release_code[r], code[i]) if compare else 0.0
        # an id-less cell is paired by place, the closer in source the better
        return (_BY_ID if kept and ids[i] is not None else 1.0) + similarity

    return {sub[b]: rel[a] for a, b in _monotone_pairs(len(rel), len(sub), weight)}


def _find_graders(n_cells: int, release, originals: dict[int, int], candidates: dict) -> dict[int, int]:
    """Submission index -> release index of the one cell taken as each released grader."""
    at = {r: i for i, r in originals.items()}  # released cell -> where the learner's copy of it is
    found, previous = {}, -1
    for r, ref in enumerate(release.cells):
        if not _is_grader(ref):
            continue
        before = max((at[p] for p in at if p < r), default=-1)
        after = min((at[p] for p in at if p > r), default=n_cells)
        ranked = [(rank, before < i < after, i > previous, -i) for i, rank in candidates.get(r, []) if i not in found]
        if ranked:
            i = -max(ranked)[-1]
            found[i], previous = r, i
    return found


#: Characters of a cell's first line that its label quotes.
_QUOTED = 40


def _first_line(cell) -> str:
    """``; first line "..."``: what finds a cell that its id cannot (none for an empty cell)."""
    line = next((line.strip() for line in _code_lines(_source(cell)) if line.strip()), "")
    if not line:
        return "; empty"
    return f'; first line "{line if len(line) <= _QUOTED else line[:_QUOTED - 1] + "…"}"'


def _labels(cells, ids) -> list[str]:
    where: dict[str, list[int]] = {}
    for i, cid in enumerate(ids):
        if cid is not None:
            where.setdefault(cid, []).append(i)
    labels = []
    for i, cid in enumerate(ids):
        if cid is not None and len(where[cid]) == 1:
            labels.append(f"cell {cid}")
        elif cid is not None:
            others = [str(j + 1) for j in where[cid] if j != i]
            labels.append(f"cell {i + 1} (id {cid}, also used by cell{'s' if len(others) > 1 else ''} "
                          f"{', '.join(others)}{_first_line(cells[i])})")
        else:
            raw = _raw_id(cells[i])
            labels.append(f"cell {i + 1} ({'no id' if raw is None or raw == '' else 'invalid id'}"
                          f"{_first_line(cells[i])})")
    return labels


def _run_ids(ids, graders: dict[int, int], release) -> list[str]:
    """Unique ids for the notebook that runs (its errors and verdicts are reported by id)."""
    reserved = {ref["id"] for ref in release.cells if _is_grader(ref)}
    counts = Counter(ids)
    used = reserved | {cid for cid in ids if cid is not None}
    out = []
    for i, cid in enumerate(ids):
        if i in graders:
            out.append(release.cells[graders[i]]["id"])
        elif cid is not None and counts[cid] == 1 and cid not in reserved:
            out.append(cid)
        else:
            new = f"cell-{i + 1}"
            while new in used:
                new += "x"
            used.add(new)
            out.append(new)
    return out


def identify_cells(submission, release) -> Identified:
    """Say which cell of ``submission`` is which cell of ``release`` (see the module docstring).

    Parameters
    ----------
    submission : NotebookNode
        A learner's notebook as read, whatever its cells' ids and metadata.
    release : NotebookNode
        The released exercise of its chapter.

    Returns
    -------
    Identified
    """
    cells = submission.cells
    ids = [cell_id(cell) for cell in cells]
    code = [_code_lines(_source(cell)) for cell in cells]
    release_code = [_code_lines(ref.source) for ref in release.cells]
    release_ids = {ref.get("id") for ref in release.cells}
    kept = any(cid in release_ids for cid in ids if cid is not None)
    candidates: dict[int, list] = {}
    for r, ref in enumerate(release.cells):
        if _is_grader(ref):
            candidates[r] = [(i, rank) for i, cell in enumerate(cells)
                             if (rank := _grader_rank(cell, ids[i], code[i], ref, release_code[r], kept))]
    could_grade = {i for ranks in candidates.values() for i, _ in ranks}
    originals = _learner_originals(cells, ids, code, release, release_code, kept, could_grade)
    graders = _find_graders(len(cells), release, originals, candidates)
    return Identified(
        labels=_labels(cells, ids), ids=ids, run_ids=_run_ids(ids, graders, release), graders=graders,
        originals=originals, kept_ids=kept,
        dropped_tags=not any(cell_tags(cell) for cell in cells),
        dropped_grading=not any("kalman_course" in cell_metadata(cell) for cell in cells))
