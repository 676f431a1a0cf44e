"""What marks a cell in the course's notebooks: grader cells, their tags, the learner's fix lines.

Shared by the exercise builder, the grader and the code review (so that none of them
imports another for a constant).
"""

from __future__ import annotations

import re

#: The comment that ends every stub line a learner must fix.
FIX_THIS = "# fix this"

#: The lines that mark a fix region of a solution (never in an exercise: a copy carries them).
BEGIN_RE = re.compile(r"^(?P<indent>[ \t]*)# BEGIN SOLUTION (?P<check>[A-Za-z_][\w]*)[ \t]*$")
STUB_RE = re.compile(r"^[ \t]*# STUB[ \t]*$")
END_RE = re.compile(r"^[ \t]*# END SOLUTION[ \t]*$")

GRADER_TAG = "grader"
CHECK_OUTPUT_TAG = "nbval-check-output"
IGNORE_OUTPUT_TAG = "nbval-ignore-output"


class AuthoringError(ValueError):
    """A solution notebook's markers or grader cells are malformed."""


def grader_info(cell) -> tuple[str, int] | None:
    """Return (check name, points) if ``cell`` is a grader cell, else None."""
    if cell.cell_type != "code" or GRADER_TAG not in cell.metadata.get("tags", []):
        return None
    meta = cell.metadata.get("kalman_course", {})
    if "check" not in meta or not isinstance(meta.get("points"), int) or meta["points"] <= 0 \
            or not isinstance(meta.get("challenge", False), bool):
        raise AuthoringError(f"grader cell {cell.get('id')!r} needs metadata kalman_course = "
                             "{'check': NAME, 'points': positive int} (and optionally 'challenge': true)")
    return meta["check"], meta["points"]


def is_challenge(cell) -> bool:
    """Whether a grader cell grades an optional challenge (its points are counted apart)."""
    return grader_info(cell) is not None and cell.metadata["kalman_course"].get("challenge", False)
