"""Chapter 01: the histogram filter when its model of the world is wrong.

The filter is exact only for the world it models. :func:`corridor_trials` runs it on a
simulated circular corridor whose truth (map, sensor, motion) may differ from what the
filter assumes, over many seeds, and reports how often its best guess is the true cell
(its accuracy) and how probable it says its best guess is (its confidence). With the right
model the two agree on average; a wrong model shows as a gap between them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_seeds
from kalman_course.filters import bayes

__all__ = ["CorridorModel", "CalibrationResult", "corridor_trials"]


@dataclass(frozen=True)
class CorridorModel:
    """A circular corridor: its map, its door sensor and its motion.

    Attributes
    ----------
    doors : tuple of bool
        One entry per cell, True where the cell has a door.
    p_hit : float
        p(reading "door" | the cell has a door).
    p_false : float
        p(reading "door" | the cell is wall).
    step_probs : tuple of (int, float)
        (cells moved per step, its probability) pairs; the probabilities sum to one.
    """

    doors: tuple
    p_hit: float
    p_false: float
    step_probs: tuple

    def __post_init__(self):
        if len(self.doors) < 2:
            raise ValueError(f"doors must describe at least two cells, got {len(self.doors)}")
        for name in ("p_hit", "p_false"):
            value = getattr(self, name)
            if not 0.0 < value < 1.0:
                raise ValueError(f"{name} must be a probability strictly between 0 and 1, got {value!r}")
        probs = [p for _, p in self.step_probs]
        if not probs or min(probs) < 0.0 or not np.isclose(sum(probs), 1.0):
            raise ValueError(f"step_probs must be (offset, probability) pairs summing to one, got {self.step_probs!r}")

    @property
    def n(self) -> int:
        """Number of cells."""
        return len(self.doors)

    def door_probability(self) -> np.ndarray:
        """p(reading "door" | x = i) for every cell i, shape (n,)."""
        return np.where(np.asarray(self.doors, dtype=bool), self.p_hit, self.p_false)


@dataclass(frozen=True)
class CalibrationResult:
    """What the filter believed at its last step against what was true, over the seeds.

    Attributes
    ----------
    correct : numpy.ndarray of bool, shape (n_seeds,)
        Whether the best guess (the most probable cell) was the true cell.
    confidence : numpy.ndarray, shape (n_seeds,)
        The posterior probability of the best guess.
    """

    correct: np.ndarray
    confidence: np.ndarray

    @property
    def accuracy(self) -> float:
        """Share of the runs whose best guess was right."""
        return float(np.mean(self.correct))

    @property
    def mean_confidence(self) -> float:
        """Mean posterior probability of the best guess: the accuracy the filter expects."""
        return float(np.mean(self.confidence))

    @property
    def standard_error(self) -> float:
        """Standard error of :attr:`accuracy` as a binomial share, √(a(1 − a)/N)."""
        a, n = self.accuracy, len(self.correct)
        return float(np.sqrt(max(a * (1.0 - a), 1.0 / n) / n))


def _one_run(filter_model: CorridorModel, truth: CorridorModel, rng, steps: int, transition) -> tuple[bool, float]:
    offsets = np.array([k for k, _ in truth.step_probs])
    probs = np.array([p for _, p in truth.step_probs])
    true_door, filter_door = truth.door_probability(), filter_model.door_probability()
    cell = int(rng.integers(truth.n))
    belief = np.full(filter_model.n, 1.0 / filter_model.n)        # the start is unknown
    for k in range(steps):
        if k > 0:
            cell = int((cell + rng.choice(offsets, p=probs)) % truth.n)
            belief = bayes.histogram_predict(belief, transition)
        says_door = rng.random() < true_door[cell]
        belief = bayes.histogram_update(belief, filter_door if says_door else 1.0 - filter_door)
    best = int(np.argmax(belief))
    return best == cell, float(belief[best])


def corridor_trials(filter_model: CorridorModel, truth: CorridorModel, seeds, steps: int = 20) -> CalibrationResult:
    """Run the histogram filter of ``filter_model`` on worlds simulated from ``truth``.

    Each seed draws the start cell, the steps and the readings from ``truth`` (simulated);
    the filter starts from a uniform belief and predicts and updates with its own model.

    Parameters
    ----------
    filter_model : CorridorModel
        What the filter assumes.
    truth : CorridorModel
        What generates the simulated world; the same number of cells.
    seeds : sequence of int
        One run per seed.
    steps : int
        Readings per run (the first is an update only).

    Returns
    -------
    CalibrationResult
    """
    for name, model in (("filter_model", filter_model), ("truth", truth)):
        if not isinstance(model, CorridorModel):
            raise ValueError(f"{name} must be a CorridorModel, got {type(model).__name__}")
    if filter_model.n != truth.n:
        raise ValueError(f"filter_model and truth must have the same number of cells, got {filter_model.n} and {truth.n}")
    seeds = as_seeds(seeds)
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be a positive int, got {steps!r}")
    transition = bayes.circular_motion_model(filter_model.n, dict(filter_model.step_probs))
    runs = [_one_run(filter_model, truth, np.random.default_rng(seed), int(steps), transition) for seed in seeds]
    return CalibrationResult(np.array([r[0] for r in runs]), np.array([r[1] for r in runs]))
