"""Hints in tiers: the concept and the lecture section first, the formula when asked for.

A hint that hands over the formula at the first failure teaches copying, not the idea. So a
check writes each hint as the concept it is about and where the lecture derives it, and puts
the formula itself in :func:`formula`. Which tier a learner sees:

- **tier 1** (the default): the concept and the section; the formula parts are left out and
  the message says how to see them;
- **tier 2**: the whole hint. A grader cell shows it when the same check fails a second
  time with the same message (the learner has read tier 1 and is still stuck), or after
  ``checks.more_hints()``; ``kalman-course grade --all-hints`` grades at tier 2, and the
  gradebook records the tier.

The formula parts are marked with two control characters in the message text, and
:func:`render` turns a marked message into what the learner reads at a tier. Rendering
happens once per failure, where the check's verdict is made (``harness.check``), so cached
cases may hold marked hints whatever the tier.
"""

from __future__ import annotations

import re

__all__ = ["formula", "render", "tier", "settings", "set_tier", "more_hints", "escalates", "TIERS"]

#: The tiers: what each one shows.
TIERS = {1: "concepts and lecture sections", 2: "concepts, sections and formulas"}

_START, _END = "\x02", "\x03"  # around a formula part of a hint
_MARKED = re.compile(f"{_START}(.*?){_END}", re.S)
_GAP = "\x00"  # where a left-out part was, while the text around it is tidied

#: What a tier-1 message says when it left something out, per place the checks run in.
IN_NOTEBOOK = "run this grader cell again, or call checks.more_hints(), for the formula"
WHEN_GRADED = "the formula is shown at hint tier 2 (kalman-course grade --all-hints)"

_state = {"tier": 1, "escalate": True, "more": IN_NOTEBOOK}


def formula(text: str) -> str:
    """Mark ``text`` (a formula, or a sentence that gives one away) as tier 2 of a hint."""
    return f"{_START}{text}{_END}"


def tier() -> int:
    """The tier the checks' messages are rendered at (1 or 2)."""
    return _state["tier"]


def escalates() -> bool:
    """Whether a check that fails twice with the same message shows tier 2 the second time."""
    return _state["escalate"]


def settings() -> dict:
    """The current ``level``, ``escalate`` and ``more`` of :func:`set_tier`, to restore later
    with ``set_tier(**settings)``."""
    return {"level": _state["tier"], "escalate": _state["escalate"], "more": _state["more"]}


def set_tier(level: int, *, escalate: bool = True, more: str = IN_NOTEBOOK) -> None:
    """Render the checks' messages at ``level`` from now on.

    Parameters
    ----------
    level : int
        1 or 2 (see :data:`TIERS`).
    escalate : bool
        Whether a second identical failure of a check shows tier 2 (a grader cell run again).
        Off where a verdict must not depend on how often a check ran (grading a class).
    more : str
        What a tier-1 message says when it left a formula out: how to see it here.

    Raises
    ------
    ValueError
        If ``level`` is not 1 or 2.
    """
    if isinstance(level, bool) or level not in TIERS:
        raise ValueError(f"level must be one of {sorted(TIERS)}, got {level!r}")
    _state.update(tier=int(level), escalate=bool(escalate), more=str(more))


def more_hints() -> None:
    """Show the formulas in every check's hints from now on (tier 2) in this kernel."""
    set_tier(2, escalate=_state["escalate"], more=_state["more"])
    print("hints now include the formulas (tier 2)")


def render(message: str, level: int | None = None) -> str:
    """What the learner reads of a marked ``message`` at ``level`` (default: the current tier).

    At tier 2 the marks are dropped; at tier 1 the marked parts are left out, with the
    spaces and empty brackets they leave, and the message ends by saying how to see them.
    """
    level = tier() if level is None else level
    if level >= 2 or _START not in message:
        return _MARKED.sub(r"\1", message).replace(_START, "").replace(_END, "")
    # tidy only where a part was left out (the rest of the text is the check's, e.g. P[:m, :m])
    text = _MARKED.sub(_GAP, message).replace(_START, "").replace(_END, "")
    text = re.sub(rf"\s*[:;,]?\s*{_GAP}", "", text)      # the gap, with the colon or space before it
    text = re.sub(r"\(\s*\)", "", text)                 # brackets that held only the gap
    text = re.sub(r"(?<=\S)[ \t]{2,}(?=\S)", " ", text)
    text = text.rstrip(" ;:,")
    return f"{text} ({_state['more']})"


def strip(message: str) -> str:
    """``message`` with its marks removed and nothing left out (the tier-2 text)."""
    return render(message, 2)
