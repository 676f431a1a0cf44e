"""Chapter 01's world: a circular corridor of doors and walls, and a robot moving round it.

The lecture, the exercise and its checks share this scenario, so it lives here rather than
in the checks (a graded kernel has no :mod:`kalman_course.checks`).
"""

from __future__ import annotations

import math

import numpy as np

from kalman_course.core.validation import as_int, as_seed, as_vector

__all__ = ["CORRIDOR", "scenario", "corridor_scenario"]

#: The corridor's map: 1 where a cell has a door, 0 where it is wall (20 cells, a ring).
CORRIDOR = np.array([1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0])


def scenario(world, seed: int, steps: int, p_correct: float, step_probs: dict):
    """A robot moving around a circular ``world``, with its true cells and noisy door readings.

    Parameters
    ----------
    world : ndarray (n,)
        The map, 1 for a door, 0 for a wall.
    seed : int
        Seeds the robot's start, its steps and the sensor's errors.
    steps : int
        The number of readings.
    p_correct : float
        The probability that a reading tells door from wall correctly.
    step_probs : dict of int to float
        Offset (cells moved per step) -> its probability.

    Returns
    -------
    cells : ndarray (steps,) of int
        The true cell at each reading.
    z : ndarray (steps,)
        The readings (1 door, 0 wall).
    transition : ndarray (n, n)
        The motion model: column j holds ``step_probs[k]`` in row (j + k) mod n. It equals
        ``bayes.circular_motion_model(n, step_probs)`` (a test proves it), but is built
        without it: the lecture runs the filter before the exercise asks for that function,
        and a graded kernel withholds the course's own.
    p_correct : float
        As given.
    """
    world, seed, steps, p_correct, step_probs = _checked(world, seed, steps, p_correct, step_probs)
    rng = np.random.default_rng(seed)
    n = len(world)
    offsets, probs = zip(*step_probs.items())
    cells = [int(rng.integers(n))]
    for _ in range(steps - 1):
        cells.append((cells[-1] + int(rng.choice(offsets, p=probs))) % n)
    cells = np.array(cells)
    z = np.where(rng.random(steps) < p_correct, world[cells], 1 - world[cells])
    transition = sum(p * np.roll(np.eye(n), k, axis=0) for k, p in step_probs.items())
    return cells, z, transition, p_correct


def _checked(world, seed, steps, p_correct, step_probs):
    """The arguments of :func:`scenario`, validated (each error names its argument)."""
    world_arr = as_vector(world, "world")
    if not np.isin(world_arr, (0.0, 1.0)).all():
        raise ValueError(f"world must hold 1 (door) or 0 (wall) in each cell, got {world_arr}")
    if isinstance(world, np.ndarray) and world.dtype.kind in "iu":
        world_arr = world                  # keep the caller's integer map (readings are its values)
    seed = as_seed(seed)
    steps = as_int(steps, "steps", minimum=1)
    if (isinstance(p_correct, (bool, np.bool_, str, bytes)) or not isinstance(p_correct, (int, float, np.number))
            or not 0.0 <= float(p_correct) <= 1.0):
        raise ValueError(f"p_correct must be a probability in [0, 1], got {p_correct!r}")
    if not isinstance(step_probs, dict) or not step_probs:
        raise ValueError(f"step_probs must be a non-empty dict of offset (int) -> probability, got {step_probs!r}")
    for k, p in step_probs.items():
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
            raise ValueError(f"step_probs keys must be integer offsets, got {k!r}")
        if (isinstance(p, (bool, np.bool_, str, bytes)) or not isinstance(p, (int, float, np.number))
                or not 0.0 <= float(p) <= 1.0):
            raise ValueError(f"step_probs[{k!r}] must be a probability in [0, 1], got {p!r}")
    if not math.isclose(sum(float(p) for p in step_probs.values()), 1.0, abs_tol=1e-9):
        raise ValueError(f"step_probs must sum to 1, got {sum(float(p) for p in step_probs.values())}")
    return world_arr, seed, steps, p_correct, step_probs


def corridor_scenario(seed: int = 7, steps: int = 12, p_correct: float = 0.85):
    """A robot moving around :data:`CORRIDOR` (mostly one cell a step), as :func:`scenario`."""
    return scenario(CORRIDOR, seed, steps, p_correct, {0: 0.1, 1: 0.8, 2: 0.1})
