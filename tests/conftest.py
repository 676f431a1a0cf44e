"""Shared fixtures: the repository's folders, a non-interactive matplotlib backend, and hints
at tier 1 without escalation (a test that runs a check twice must see the same message)."""

import textwrap
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

from kalman_course.checks import hints  # noqa: E402

hints.set_tier(1, escalate=False)


@pytest.fixture(autouse=True)
def hints_at_tier_one():
    """Every test starts from tier 1 without escalation, whatever an earlier test set (an
    in-process ``kalman-course grade`` sets the tier of its run, ``--all-hints`` tier 2)."""
    hints.set_tier(1, escalate=False)
    yield

ROOT = Path(__file__).resolve().parent.parent


def dedented(text: str) -> str:
    """A cell's source written indented in a test module: dedented, no blank first or last line."""
    return textwrap.dedent(text).strip("\n")


def first_line(source: str) -> str:
    """What a cell's label adds when its id cannot name it: ``; first line "..."`` (40
    characters at most)."""
    line = next((line.strip() for line in source.splitlines() if line.strip()), "")
    if not line:
        return "; empty"
    return f'; first line "{line if len(line) <= 40 else line[:39] + "…"}"'


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT
