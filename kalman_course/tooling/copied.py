"""Flags for a submission whose learner code is the solution's.

A cell that holds the solution's region markers (``# BEGIN SOLUTION``, ``# STUB``,
``# END SOLUTION``, which no exercise holds) was copied from ``solutions/``: it is named
whatever else it holds.

``kalman-course build`` records in each exercise a digest of every line the solution writes
into the exercise's fix regions (:func:`solution_digests`); a class is graded without
``solutions/``. :func:`copy_flags` counts how many of those lines a submission's cells hold,
spaces aside. One line in common says nothing (``return K`` is what anyone writes), so the
flag needs two things at once: nearly all of the chapter's solution lines present
(:data:`NOTEBOOK_SHARE`), and enough of them that an honest learner is unlikely to have
written every one exactly so (:data:`MIN_LINES`). Each cell that holds a region's lines
is then named. In a chapter with fewer solution lines, a copy with its markers removed
cannot be told from honest work, and is not flagged.

The digests are salted by chapter, truncated, and cover lines only: they tell whether a
given line is the solution's, which a learner with the exercise could use to confirm a
guess one line at a time, not to read the solution.
"""

from __future__ import annotations

import hashlib

from kalman_course.tooling.cells import BEGIN_RE, END_RE, STUB_RE, grader_info
from kalman_course.tooling.identify import Identified

__all__ = ["solution_digests", "copy_flags", "NOTEBOOK_SHARE", "MIN_LINES"]

#: The share of the solution's lines a submission must hold for the flag.
NOTEBOOK_SHARE = 0.9
#: The fewest solution lines a chapter must have for its copies to be told from honest work.
MIN_LINES = 12
#: Hex digits kept of each digest.
_DIGITS = 16


def _normalised(line: str) -> str:
    """A line as compared: without any white space (``a@b`` and ``a @ b`` are one line)."""
    return "".join(line.split())


def _digest(line: str, chapter: str) -> str:
    return hashlib.sha256(f"kalman-course {chapter}\n{line}".encode()).hexdigest()[:_DIGITS]


def _line_digests(source: str, chapter: str) -> set[str]:
    return {_digest(n, chapter) for line in source.splitlines() if (n := _normalised(line))}


def solution_digests(stubs, exercise, chapter: str) -> dict[str, list[str]]:
    """Digests of the lines each cell's solution regions write (what the learner writes).

    Parameters
    ----------
    stubs : list of kalman_course.tooling.authoring.Stub
        The solution's fix regions.
    exercise : NotebookNode
        The exercise built from it: lines it already holds are not the learner's work.
    chapter : str
        The two-digit chapter (the digests' salt).

    Returns
    -------
    dict of str to list of str
        Cell id -> sorted digests; stored in the exercise's metadata.
    """
    released = set().union(*(_line_digests(c.source, chapter) for c in exercise.cells if c.cell_type == "code"))
    digests: dict[str, set[str]] = {}
    for stub in stubs:
        cell = stub.stub_id.rpartition(":")[0]
        digests.setdefault(cell, set()).update(_line_digests(stub.solution, chapter) - released)
    return {cell: sorted(d) for cell, d in sorted(digests.items()) if d}


def _source(cell) -> str:
    source = cell.get("source", "")
    return source if isinstance(source, str) else ""


def copy_flags(submission, release, cells: Identified) -> list[str]:
    """``"<cell>: ..."`` for each learner cell holding the solution's markers, and for each
    holding a region's solution lines when the submission holds nearly all the chapter's
    solution lines.

    Parameters
    ----------
    submission : NotebookNode
        The learner's notebook as written.
    release : NotebookNode
        The released exercise of the same chapter.
    cells : Identified
        What each submission cell is (:func:`kalman_course.tooling.identify.identify_cells`).
    """
    learner = [i for i, c in enumerate(submission.cells)
               if c.get("cell_type") == "code" and i not in cells.graders and not grader_info(c)]
    flags = [f"{cells.labels[i]}: holds the solution's region markers (# BEGIN SOLUTION ...): copied "
             "from solutions/" for i in learner
             if any(r.match(line) for line in _source(submission.cells[i]).splitlines()
                    for r in (BEGIN_RE, STUB_RE, END_RE))]
    return flags + _line_copy_flags(submission, release, cells, learner)


def _line_copy_flags(submission, release, cells: Identified, learner: list[int]) -> list[str]:
    meta = release.metadata.get("kalman_course", {})
    recorded, chapter = meta.get("solution_digests"), meta.get("chapter")
    if not isinstance(recorded, dict) or not isinstance(chapter, str):
        return []  # a release built before the digests were recorded
    wanted = {cell: set(d) for cell, d in recorded.items() if isinstance(d, list)}
    total = set().union(*wanted.values()) if wanted else set()
    held = {i: _line_digests(_source(submission.cells[i]), chapter) for i in learner}
    found = set().union(*held.values()) & total if held else set()
    if len(total) < MIN_LINES or len(found) < NOTEBOOK_SHARE * len(total):
        return []
    flags = set()
    for region_cell, digests in wanted.items():
        holder = max(held, key=lambda i: len(held[i] & digests))
        if held[holder] >= digests:
            flags.add((holder, f"{cells.labels[holder]}: holds the solution's lines for cell {region_cell} "
                               f"character for character ({len(found)} of the chapter's {len(total)} solution "
                               "lines are in this notebook): compare it with the solution by hand"))
    return [flag for _, flag in sorted(flags)]
