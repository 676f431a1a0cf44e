"""Build learner exercises from the reference solution notebooks.

A solution notebook (``solutions/NN_name.ipynb``) is the single source of an exercise.
Inside its code cells, a *fix region* marks reference code together with the stub that
replaces it in the exercise::

    # BEGIN SOLUTION kf_predict
    P_check = F @ P_hat @ F.T + Q
    # STUB
    # P_check = F @ P_hat @ F.T  # fix this
    # END SOLUTION

The word after ``BEGIN SOLUTION`` names the grader check the stub must fail. Stub lines
are commented out in the solution (so the solution runs); the builder uncomments them
and drops the reference lines. Every stub must contain a ``# fix this`` comment.

Grader cells are code cells tagged ``grader`` whose metadata holds
``{"kalman_course": {"check": NAME, "points": N}}``. The builder gives them the id
``grader-NAME`` and the nbval tag ``nbval-check-output``; every other code cell of the
exercise is tagged ``nbval-ignore-output``, so ``pytest --nbval`` grades exactly the
grader cells. The exercise ships without outputs (nothing of the reference's results);
grader cells marked ``"challenge": true`` grade optional challenges, counted apart.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass
from pathlib import Path

from kalman_course.tooling.cells import (BEGIN_RE, CHECK_OUTPUT_TAG, END_RE,  # noqa: F401 (re-exported)
                                         FIX_THIS, GRADER_TAG, IGNORE_OUTPUT_TAG, STUB_RE, AuthoringError,
                                         grader_info, is_challenge)
from kalman_course.tooling.notebooks import (InputError, load_notebook, normalise, notebook_text, require_folder,
                                             require_output)
from kalman_course.tooling.copied import solution_digests
from kalman_course.tooling.review import solution_course_calls



@dataclass(frozen=True)
class Stub:
    """One fix region of a solution notebook.

    Attributes
    ----------
    stub_id : str
        ``"<cell id>:<n>"``, the n-th region (from 0) of that cell.
    check : str
        Name of the grader check this stub must fail.
    solution : str
        The reference lines, as in the solution.
    stub : str
        The exercise lines, uncommented.
    """

    stub_id: str
    check: str
    solution: str
    stub: str


def _parse_regions(source: str, where: str):
    """Split a cell source into text pieces and (check, solution, stub) regions."""
    pieces: list = []
    lines = source.split("\n")
    i = 0
    plain: list[str] = []
    while i < len(lines):
        m = BEGIN_RE.match(lines[i])
        if STUB_RE.match(lines[i]) or END_RE.match(lines[i]):
            raise AuthoringError(f"{where}: line {i + 1}: '{lines[i].strip()}' without '# BEGIN SOLUTION'")
        if not m:
            plain.append(lines[i])
            i += 1
            continue
        if plain:  # adjacent regions have no text between them, not an empty line
            pieces.append("\n".join(plain))
        plain = []
        indent, check = m["indent"], m["check"]
        start = i
        i += 1
        sol: list[str] = []
        while i < len(lines) and not STUB_RE.match(lines[i]):
            if BEGIN_RE.match(lines[i]) or END_RE.match(lines[i]):
                raise AuthoringError(f"{where}: region opened on line {start + 1} has no '# STUB' line")
            sol.append(lines[i])
            i += 1
        if i == len(lines):
            raise AuthoringError(f"{where}: region opened on line {start + 1} has no '# STUB' line")
        i += 1
        stub: list[str] = []
        while i < len(lines) and not END_RE.match(lines[i]):
            line = lines[i]
            if BEGIN_RE.match(line) or STUB_RE.match(line):
                raise AuthoringError(f"{where}: region opened on line {start + 1} has no '# END SOLUTION'")
            if line.strip() in ("", "#"):
                stub.append("")
            elif line.startswith(indent + "# "):
                stub.append(indent + line[len(indent) + 2:])
            else:
                raise AuthoringError(f"{where}: line {i + 1}: stub lines must be commented as "
                                     f"'{indent}# <code>', got {line!r} (or is '# END SOLUTION' missing?)")
            i += 1
        if i == len(lines):
            raise AuthoringError(f"{where}: region opened on line {start + 1} has no '# END SOLUTION'")
        i += 1
        if not sol:
            raise AuthoringError(f"{where}: region opened on line {start + 1} has no solution lines")
        if not any(FIX_THIS in line for line in stub):
            raise AuthoringError(f"{where}: the stub of region '{check}' (line {start + 1}) "
                                 f"has no '{FIX_THIS}' comment")
        pieces.append((check, "\n".join(sol), "\n".join(stub)))
    if plain:
        pieces.append("\n".join(plain))
    return pieces


def list_stubs(nb) -> list[Stub]:
    """Return every fix region of a solution notebook, in cell order."""
    stubs = []
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        regions = [p for p in _parse_regions(cell.source, f"cell {cell.get('id')}") if isinstance(p, tuple)]
        for n, (check, sol, stub) in enumerate(regions):
            stubs.append(Stub(f"{cell['id']}:{n}", check, sol, stub))
    return stubs


def render_source(source: str, chosen=None, where: str = "cell") -> str:
    """Return one cell's source with its fix regions replaced by their stubs.

    Parameters
    ----------
    source : str
        A solution cell's source.
    chosen : set of int, optional
        Which regions (numbered from 0 in the cell) to replace; None means all of them.
        Regions not chosen keep their solution lines (without markers).
    where : str
        How to name the cell in an :class:`AuthoringError`.
    """
    text, n = [], 0
    for piece in _parse_regions(source, where):
        if isinstance(piece, str):
            text.append(piece)
            continue
        _, sol, stub = piece
        text.append(stub if chosen is None or n in chosen else sol)
        n += 1
    return "\n".join(text)


def render(nb, stub_ids: set[str] | None = None):
    """Return a copy of ``nb`` with the chosen fix regions replaced by their stubs.

    Parameters
    ----------
    nb : NotebookNode
        A solution notebook.
    stub_ids : set of str, optional
        Which regions to replace (ids from :func:`list_stubs`); None means all of them.
        Regions not chosen keep their solution lines (without markers).
    """
    out = copy.deepcopy(nb)
    for cell in out.cells:
        if cell.cell_type != "code":
            continue
        chosen = None if stub_ids is None else {int(sid.rpartition(":")[2]) for sid in stub_ids
                                                if sid.rpartition(":")[0] == cell["id"]}
        cell.source = render_source(cell.source, chosen, f"cell {cell.get('id')}")
    return out


def chapter_of(path: Path) -> str:
    """Return the two-digit chapter number from a file name like ``03_kalman_filter.ipynb``."""
    m = re.match(r"^(\d\d)_", Path(path).name)
    if not m:
        raise AuthoringError(f"{path}: notebook names must start with a two-digit chapter, e.g. 03_name.ipynb")
    return m.group(1)


def build_exercise(solution_path: str | Path):
    """Return the exercise notebook generated from the solution at ``solution_path``.

    Raises
    ------
    NotebookError
        If the file is not a notebook (naming it and why).
    AuthoringError
        If markers are malformed, a stub names a check with no grader cell, a grader cell
        lacks its metadata, or a grader has no stub (it could never fail).
    """
    solution_path = Path(solution_path)
    nb = load_notebook(solution_path)
    try:
        return _exercise_of(nb, solution_path)
    except AuthoringError as exc:
        if str(exc).startswith(f"{solution_path}: "):
            raise
        raise AuthoringError(f"{solution_path}: {exc}") from None  # it names a cell; name the notebook too


def _exercise_of(nb, solution_path: Path):
    """The exercise of the solution notebook ``nb`` read from ``solution_path``."""
    stubs = list_stubs(nb)
    if not stubs:
        raise AuthoringError(f"{solution_path}: no '# BEGIN SOLUTION' regions")
    ex = render(nb)
    graders: dict[str, int] = {}
    for cell in ex.cells:
        if cell.cell_type != "code":
            continue
        tags = [t for t in cell.metadata.get("tags", []) if t not in (CHECK_OUTPUT_TAG, IGNORE_OUTPUT_TAG)]
        info = grader_info(cell)
        if info:
            check, points = info
            if check in graders:
                raise AuthoringError(f"{solution_path}: two grader cells check {check!r}")
            graders[check] = points
            cell["id"] = f"grader-{check}"
            tags.append(CHECK_OUTPUT_TAG)
        else:
            tags.append(IGNORE_OUTPUT_TAG)
        cell.metadata["tags"] = tags
        # The learner starts from a blank page: no output of the reference is shipped (no
        # "passed" lines, plots or printed results). nbval compares no output of a cell
        # that was never run, so each cell is judged by whether it raises.
        cell.outputs = []
        cell.execution_count = None
    for stub in stubs:
        if stub.check not in graders:
            raise AuthoringError(f"{solution_path}: stub {stub.stub_id} names check {stub.check!r}, "
                                 f"which has no grader cell (graders: {sorted(graders)})")
    unguarded = sorted(set(graders) - {s.check for s in stubs})
    if unguarded:
        raise AuthoringError(f"{solution_path}: grader cells {unguarded} have no stub that should fail them")
    ex.metadata["kalman_course"] = {
        "chapter": chapter_of(solution_path),
        "source": f"solutions/{solution_path.name}",
        "graders": graders,
        # optional challenges: graded like the rest, their points counted apart
        "challenges": sorted(grader_info(c)[0] for c in ex.cells if is_challenge(c)),
        # what a correct version of each function to write calls of the course's code: the
        # review's baseline (a learner calling anything else of it is worth a look)
        "course_calls": solution_course_calls(nb, ex),
        # what a copy of the solution would hold, line by line (the review needs no solutions/)
        "solution_digests": solution_digests(stubs, ex, chapter_of(solution_path)),
        "generated": "by `kalman-course build`; edit the solution, not this file",
    }
    return normalise(ex)


#: Key of the exercise metadata (under ``kalman_course``) that holds the digest of the
#: exercise as ``build`` wrote it: a file whose content no longer matches was changed since.
BUILD_DIGEST = "build_digest"


def _content_digest(nb: dict) -> str:
    """sha256 (16 hex digits) of ``nb`` in the canonical layout, without its build digest."""
    import hashlib

    nb = copy.deepcopy(nb)
    nb.get("metadata", {}).get("kalman_course", {}).pop(BUILD_DIGEST, None)
    return hashlib.sha256(notebook_text(nb).encode("utf-8")).hexdigest()[:16]


def _with_build_digest(nb) -> str:
    """The exercise's text with the digest of its own content recorded in its metadata."""
    nb.metadata.setdefault("kalman_course", {})[BUILD_DIGEST] = _content_digest(nb)
    return notebook_text(nb)


def written_by_build(text: str) -> bool:
    """Whether ``text`` (a notebook file's content) is an exercise exactly as ``build`` wrote
    it: its recorded build digest matches its content (layout aside: an editor that only
    re-saves it changes nothing that counts)."""
    import json

    try:
        nb = json.loads(text)
        recorded = nb["metadata"]["kalman_course"][BUILD_DIGEST]
    except (ValueError, KeyError, TypeError):
        return False
    try:
        return recorded == _content_digest(nb)
    except Exception:  # not a notebook nbformat can write: not the build's
        return False


class BuildRefused(AuthoringError):
    """Exercises changed since the last build, left as they are; ``.refused`` lists them."""

    def __init__(self, refused: list[Path], written: list[Path]):
        self.refused, self.written = refused, written
        names = ", ".join(str(p) for p in refused)
        super().__init__(f"not overwritten, changed since the last build (your work?): {names}")


def _backup_path(target: Path) -> Path:
    """``NN_name.ipynb.bak``, or ``.bak2``, ``.bak3``, … if taken (never an exercise's name)."""
    n = 1
    while True:
        candidate = target.with_name(target.name + (".bak" if n == 1 else f".bak{n}"))
        if not candidate.exists():
            return candidate
        n += 1


def build_all(solutions_dir: str | Path, exercises_dir: str | Path, *, check: bool = False,
              force: bool = False) -> list[Path]:
    """Write (or, with ``check``, compare) every exercise generated from ``solutions_dir``.

    An exercise file that changed since the build that wrote it (a learner's work: its
    content no longer matches the build digest in its metadata, or it has none) is not
    overwritten: the others are written, then :class:`BuildRefused` names it. With
    ``force`` it is overwritten after a copy is kept beside it (``NN_name.ipynb.bak``,
    ``.bak2``, …).

    Returns
    -------
    list of Path
        The exercise files that were out of date (with ``check``) or rewritten.

    Raises
    ------
    BuildRefused
        If some exercises were left as they are (``.written`` lists what was written).
    InputError
        Before anything is written, if a folder is missing or a file, a solution is not a
        notebook, or an exercise's place holds a folder or a file that cannot be read.
    AuthoringError
        Before anything is written, if a solution's fix regions or grader cells are malformed.
    """
    solutions_dir = require_folder(solutions_dir, "a folder of solution notebooks (--solutions)")
    exercises_dir = require_output(exercises_dir, "the folder the exercises are written to (--exercises)",
                                   folder=True)
    sources = sorted(solutions_dir.glob("[0-9][0-9]_*.ipynb"))
    if not sources:
        raise InputError(solutions_dir, "no solution notebooks (NN_name.ipynb) in it",
                         "a folder of solution notebooks (--solutions)")
    # every solution is read and built, and every exercise file read, before anything is written:
    # one that cannot be changes nothing
    built = [(exercises_dir / src.name, build_exercise(src)) for src in sources]
    current = {target: _current_exercise(target) for target, _ in built}
    changed, refused = [], []
    for target, exercise in built:
        undigested = notebook_text(exercise)      # what a build before the digests wrote
        text = _with_build_digest(exercise)
        if current[target] == text:
            continue
        if check:
            changed.append(target)
            continue
        if current[target] is not None and current[target] != undigested and not written_by_build(current[target]):
            if not force:
                refused.append(target)
                continue
            _backup_path(target).write_text(current[target], encoding="utf-8")
        exercises_dir.mkdir(parents=True, exist_ok=True)
        target.write_text(text, encoding="utf-8")
        changed.append(target)
    if check:
        expected = {target for target, _ in built}
        changed.extend(sorted(p for p in exercises_dir.glob("[0-9][0-9]_*.ipynb") if p not in expected))
    if refused:
        raise BuildRefused(refused, changed)
    return changed


def _current_exercise(target: Path) -> str | None:
    """The text of the exercise file at ``target`` (undecodable bytes replaced), None if there is
    none; :class:`InputError` naming it if it is a folder or cannot be read."""
    expected = "an exercise file kalman-course build writes (move it away)"
    if not target.exists() and not target.is_symlink():
        return None
    if target.is_dir():
        raise InputError(target, "a folder where the build writes an exercise", expected)
    try:
        return target.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise InputError(target, f"cannot be read ({exc.strerror or exc})", expected) from None
