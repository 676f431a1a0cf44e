"""The guard that stands in for a reference implementation while a notebook is graded.

``kalman-course grade`` runs each learner's kernel on a build of this package in which the
course's own versions of the functions that chapter's exercise asks for have no body: each
calls :func:`withheld` instead, which records who called it and raises
:class:`ReferenceWithheld`. Outside grading (lectures, a learner's JupyterLab) nothing here is
ever called.
"""

from __future__ import annotations

import sys

__all__ = ["ReferenceWithheld", "withheld", "calls"]

#: (file name of the calling code, line, withheld function, the exercise function it stands
#: for) of every call, in order.
_CALLS: list[tuple[str, int, str, str]] = []
_PACKAGE_FILES = __file__.rsplit("core", 1)[0]


class ReferenceWithheld(RuntimeError):
    """A learner's code called a reference implementation that grading withholds."""


def withheld(dotted: str, exercise_function: str, chapter: str):
    """Record a call of the withheld ``dotted`` and raise :class:`ReferenceWithheld`.

    Parameters
    ----------
    dotted : str
        The withheld function's full name (``kalman_course.filters.kf.kf_update``).
    exercise_function : str
        The function of the exercise it stands for (``kf_update``).
    chapter : str
        The chapter whose exercise is graded (``03``).
    """
    frame = sys._getframe(1)
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE_FILES):
        frame = frame.f_back  # the first caller outside the package: the learner's cell
    if frame is not None:  # (the kernel's own code when the grader called the guard itself)
        _CALLS.append((frame.f_code.co_filename, frame.f_lineno, dotted, exercise_function))
    raise ReferenceWithheld(
        f"{dotted} is not available while grading: chapter {chapter}'s exercise asks you to write "
        f"{exercise_function} yourself, so the course's own version is withheld from your kernel")


def calls() -> list[tuple[str, int, str, str]]:
    """The calls recorded so far (a copy)."""
    return list(_CALLS)
