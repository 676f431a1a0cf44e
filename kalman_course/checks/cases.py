"""Where a check's inputs come from: fixed for the learner's self-check, drawn for a graded run.

A grader cell in JupyterLab checks the learner's function on fixed cases, the same on every
machine, so that a learner sees the same message every time. Fixed inputs are public, so a
submission could carry a table from their digest to outputs computed at home with the
course's reference. An instructor's ``kalman-course grade`` therefore draws the inputs from
a *run seed* it holds (and records in the gradebook, so that any grade can be reproduced):
each check's cases come from the same family as its fixed ones (the same shapes, noise levels
on both sides of 1, dense covariances, angles near 0 and ±π, ...), but with values no
table made beforehand can hold.

A check asks for its randomness with :func:`rng` (a generator seeded by the check's own tag,
mixed with the run seed when there is one) and for a choice between a fixed case and a drawn
one with :func:`fixed_or_drawn`. The cached case functions of the checks (``functools``
caches of zero-argument functions) are cleared whenever the run seed changes.
"""

from __future__ import annotations

import functools
import sys
import zlib
from typing import Callable, TypeVar

import numpy as np

__all__ = ["run_seed", "set_run_seed", "rng", "fixed_or_drawn", "drawing"]

T = TypeVar("T")

#: The run seed of this process (None: the fixed cases of the self-check).
_RUN_SEED: int | None = None

#: Largest run seed accepted (what ``secrets.randbits(63)`` draws).
MAX_SEED = 2**63 - 1


def run_seed() -> int | None:
    """The run seed the checks draw their inputs from, or None for the fixed cases."""
    return _RUN_SEED


def drawing() -> bool:
    """Whether the checks draw their inputs (a run seed is set)."""
    return _RUN_SEED is not None


def set_run_seed(seed: int | None) -> None:
    """Draw the checks' inputs from ``seed`` from now on (None: back to the fixed cases).

    Raises
    ------
    ValueError
        If ``seed`` is not None or an integer in [0, 2⁶³).
    """
    global _RUN_SEED
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
                             or not 0 <= int(seed) <= MAX_SEED):
        raise ValueError(f"seed must be None or an integer in [0, 2**63), got {seed!r}")
    seed = None if seed is None else int(seed)
    if seed != _RUN_SEED:
        _RUN_SEED = seed
        _clear_case_caches()


def rng(tag: str, fixed_seed: int | list = 0) -> np.random.Generator:
    """The random generator of one family of cases.

    Parameters
    ----------
    tag : str
        Names the family (``"kf.update"``); two families never share a stream.
    fixed_seed : int or list of int
        The seed of the self-check's fixed cases (used when no run seed is set).

    Returns
    -------
    numpy.random.Generator
        Seeded by ``fixed_seed`` alone for the self-check; by the run seed, the tag and
        ``fixed_seed`` when a run seed is set.
    """
    fixed = list(np.atleast_1d(fixed_seed).astype(np.int64))
    if _RUN_SEED is None:
        return np.random.default_rng(fixed if len(fixed) > 1 else fixed[0])
    return np.random.default_rng([_RUN_SEED, zlib.crc32(tag.encode()), *fixed])


def fixed_or_drawn(fixed: T, draw: Callable[[np.random.Generator], T], tag: str) -> T:
    """``fixed`` for the self-check, else ``draw(rng(tag))``: for a family whose fixed cases
    are written out (a tuple of time steps and noise levels) rather than drawn."""
    return fixed if _RUN_SEED is None else draw(rng(tag))


def log_uniform(generator: np.random.Generator, low: float, high: float, size=None):
    """Values spread evenly in log scale over [low, high] (noise levels, time steps)."""
    return np.exp(generator.uniform(np.log(low), np.log(high), size))


def _clear_case_caches() -> None:
    """Forget every cached case of the checks' modules (they were drawn from the old seed)."""
    for name, module in list(sys.modules.items()):
        if not name.startswith("kalman_course.checks.") or module is None:
            continue
        for value in list(vars(module).values()):
            if isinstance(value, functools._lru_cache_wrapper):
                value.cache_clear()
