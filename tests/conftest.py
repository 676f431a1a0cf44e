"""Shared fixtures: the repository's folders and a non-interactive matplotlib backend."""

import textwrap
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

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
