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


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT
