"""The solution's code handed in is flagged, cell by cell; honest work is not.

A copy is told by the solution's region markers (which no exercise holds), or, in a chapter
whose solution writes enough lines, by nearly all of them present character for character
(spaces aside), measured against the digests ``kalman-course build`` records in the release.
"""

from __future__ import annotations

import copy
import json

import nbformat
import pytest

from kalman_course.tooling import authoring, copied
from kalman_course.tooling.identify import identify_cells

from conftest import ROOT

CHAPTERS = sorted(p.name for p in (ROOT / "solutions").glob("[0-9][0-9]_*.ipynb"))


def _release(chapter: str):
    return nbformat.read(ROOT / "exercises" / chapter, as_version=4)


def _solution(chapter: str):
    return nbformat.read(ROOT / "solutions" / chapter, as_version=4)


def _lines_recorded(chapter: str) -> int:
    digests = _release(chapter).metadata["kalman_course"]["solution_digests"]
    return len(set().union(*map(set, digests.values())))


def _solved(chapter: str, edit=None):
    """The release with the solution's code (no markers) in every learner cell it writes in."""
    release = _release(chapter)
    sources = {c["id"]: c.source for c in authoring.render(_solution(chapter), set()).cells}
    for cell in release.cells:
        if not authoring.grader_info(cell) and cell["id"] in sources:
            cell.source = sources[cell["id"]] if edit is None else edit(cell["id"], sources[cell["id"]])
    return release


def _flags(submission, chapter: str) -> list[str]:
    release = _release(chapter)
    return copied.copy_flags(submission, release, identify_cells(submission, release))


def _region_cells(chapter: str) -> list[str]:
    return sorted({stub.stub_id.rpartition(":")[0] for stub in authoring.list_stubs(_solution(chapter))})


BIG = [c for c in CHAPTERS if _lines_recorded(c) >= copied.MIN_LINES]
SMALL = [c for c in CHAPTERS if c not in BIG]


def test_the_chapters_split_as_the_readme_says():
    assert len(BIG) >= 4 and SMALL, (BIG, SMALL)


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_the_solution_notebook_handed_in_is_flagged_in_every_cell_it_writes(chapter):
    flags = _flags(_solution(chapter), chapter)
    assert sorted(f.split(":")[0] for f in flags if "region markers" in f) == \
        sorted(f"cell {cid}" for cid in _region_cells(chapter))


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_one_pasted_solution_cell_is_flagged_by_its_markers(chapter):
    submission = _release(chapter)
    cid = _region_cells(chapter)[0]
    pasted = next(c for c in _solution(chapter).cells if c.get("id") == cid)
    cell = nbformat.v4.new_code_cell(pasted.source)  # a new cell, no id kept
    del cell["id"]
    submission.cells.append(cell)
    flags = _flags(submission, chapter)
    first = pasted.source.splitlines()[0].strip()
    assert len(flags) == 1 and flags[0].startswith(f"cell {len(submission.cells)} (no id; first line "), flags
    assert first[:20] in flags[0]


@pytest.mark.parametrize("chapter", BIG)
def test_the_solution_code_without_markers_is_flagged_cell_by_cell(chapter):
    flags = _flags(_solved(chapter), chapter)
    recorded = _release(chapter).metadata["kalman_course"]["solution_digests"]
    assert sorted(f.split(":")[0] for f in flags) == sorted(f"cell {cid}" for cid in recorded)
    assert all("character for character" in f for f in flags)


def _marked(chapter: str, count: int):
    """An edit that makes the first ``count`` solution lines of the regions the learner's own
    (a comment of their own at the end of each)."""
    left = {"n": count}
    solution_lines = {line for stub in authoring.list_stubs(_solution(chapter)) for line in stub.solution.splitlines()}

    def edit(cid, source):
        lines = source.splitlines()
        for i, line in enumerate(lines):
            if left["n"] and line.strip() and line in solution_lines:
                lines[i], left["n"] = line + "  # mine", left["n"] - 1
        return "\n".join(lines)
    return edit


@pytest.mark.parametrize("chapter", BIG)
def test_a_near_copy_is_flagged_and_a_partial_one_is_not(chapter):
    total = _lines_recorded(chapter)
    near = _flags(_solved(chapter, _marked(chapter, 1)), chapter)
    assert near and len(near) < len(_flags(_solved(chapter), chapter)), "one line changed: its cell is not named"
    assert _flags(_solved(chapter, _marked(chapter, total // 2)), chapter) == []


@pytest.mark.parametrize("chapter", SMALL)
def test_in_a_chapter_of_few_lines_the_code_alone_is_not_a_copy(chapter):
    """The limit README states: few canonical lines (``P_check = F @ P_hat @ F.T + Q``) are
    what an honest learner writes too."""
    assert _flags(_solved(chapter), chapter) == []


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_the_release_and_a_release_without_digests_raise_no_flag(chapter):
    assert _flags(_release(chapter), chapter) == []
    release = _release(chapter)
    del release.metadata["kalman_course"]["solution_digests"]
    submission = _solved(chapter)
    assert copied.copy_flags(submission, release, identify_cells(submission, release)) == []


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_the_release_records_digests_not_the_solution_s_lines(chapter):
    text = json.dumps(_release(chapter).metadata["kalman_course"]["solution_digests"])
    for stub in authoring.list_stubs(_solution(chapter)):
        for line in stub.solution.splitlines():
            if len(line.strip()) > 8:
                assert line.strip() not in text and "".join(line.split()) not in text


def test_a_malformed_digest_record_is_ignored():
    chapter = BIG[0]
    release = _release(chapter)
    release.metadata["kalman_course"]["solution_digests"] = {"x": "not a list", "y": [3, None]}
    submission = copy.deepcopy(_solved(chapter))
    assert copied.copy_flags(submission, release, identify_cells(submission, release)) == []
