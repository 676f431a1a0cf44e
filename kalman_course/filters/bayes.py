"""The histogram (discrete Bayes) filter on n cells.

Chapter 01 of the course. The state is one of n cells (for example positions along a
circular corridor) and the belief is a probability vector ``belief[i] = p(x = i)``.
The Bayes filter alternates two steps:

* **predict** (total probability): :math:`p(x_k = i) = \\sum_j p(x_k = i \\mid x_{k-1} = j)
  \\, p(x_{k-1} = j)`, i.e. a matrix–vector product with a column-stochastic
  transition matrix;
* **update** (Bayes' rule): :math:`p(x_k = i \\mid y_k) = p(y_k \\mid x_k = i)\\,
  p(x_k = i) / p(y_k)`, where the evidence :math:`p(y_k) = \\sum_i p(y_k \\mid x_k = i)\\,
  p(x_k = i)` is the normaliser.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_matrix, as_scalar, as_vector

__all__ = [
    "normalise",
    "histogram_update",
    "histogram_predict",
    "circular_motion_model",
]

#: Absolute tolerance for "sums to one" (beliefs, transition columns, step probabilities).
_SUM_ATOL = 1e-8


def _as_nonnegative_vector(value, name: str, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite, non-negative 1-D float array (length n if given)."""
    arr = as_vector(value, name, n)
    if np.any(arr < 0):
        raise ValueError(f"{name} must be non-negative, got minimum {arr.min():.3g}")
    return arr


def _as_belief(value, name: str = "belief", n: int | None = None) -> np.ndarray:
    """Return ``value`` as a probability vector: 1-D, non-negative, summing to one."""
    arr = _as_nonnegative_vector(value, name, n)
    total = arr.sum()
    if abs(total - 1.0) > _SUM_ATOL:
        raise ValueError(f"{name} must sum to 1 (a probability vector), got sum {total:.12g}; "
                         f"use normalise() first")
    return arr


def normalise(belief):
    """Scale a non-negative vector so that it sums to one.

    Parameters
    ----------
    belief : array_like, shape (n,)
        Non-negative, unnormalised weights (for example belief × likelihood).

    Returns
    -------
    ndarray, shape (n,)
        ``belief / belief.sum()``.

    Raises
    ------
    ValueError
        If ``belief`` is not 1-D, not finite, has a negative entry, or sums to zero.
    """
    belief = _as_nonnegative_vector(belief, "belief")
    total = belief.sum()
    if total <= 0.0:
        raise ValueError("belief must have a positive sum to be normalised, got all zeros")
    return belief / total


def histogram_update(belief, likelihood):
    """Bayes' rule on n cells: posterior ∝ likelihood × prior.

    .. math::

        p(x = i \\mid y) = \\frac{p(y \\mid x = i)\\, p(x = i)}{\\sum_j p(y \\mid x = j)\\,
        p(x = j)}

    Parameters
    ----------
    belief : array_like, shape (n,)
        Prior :math:`p(x = i)`, a probability vector.
    likelihood : array_like, shape (n,)
        :math:`p(y \\mid x = i)` for the measurement y received, non-negative. It need not
        sum to one (it is a function of x, not a distribution over x).

    Returns
    -------
    ndarray, shape (n,)
        Posterior :math:`p(x = i \\mid y)`, summing to one.

    Raises
    ------
    ValueError
        If ``belief`` is not a probability vector, ``likelihood`` is not a non-negative
        vector of the same length, or the evidence :math:`p(y)` is zero (the measurement
        is impossible under the prior).
    """
    belief = _as_belief(belief, "belief")
    likelihood = _as_nonnegative_vector(likelihood, "likelihood", belief.shape[0])

    unnormalised = likelihood * belief
    evidence = unnormalised.sum()                     # p(y)
    if evidence <= 0.0:
        raise ValueError("likelihood gives zero evidence p(y) = sum(likelihood * belief): "
                         "the measurement is impossible wherever belief is non-zero")
    return unnormalised / evidence


def histogram_predict(belief, transition):
    """Prediction by total probability: belief ← transition @ belief.

    .. math::

        p(x_k = i) = \\sum_j p(x_k = i \\mid x_{k-1} = j)\\, p(x_{k-1} = j)

    Parameters
    ----------
    belief : array_like, shape (n,)
        :math:`p(x_{k-1} = j)`, a probability vector.
    transition : array_like, shape (n, n)
        ``transition[i, j]`` = :math:`p(x_k = i \\mid x_{k-1} = j)`: non-negative, every
        column sums to one.

    Returns
    -------
    ndarray, shape (n,)
        :math:`p(x_k = i)`, summing to one.

    Raises
    ------
    ValueError
        If ``belief`` is not a probability vector, or ``transition`` is not an (n, n)
        non-negative matrix whose columns sum to one.
    """
    belief = _as_belief(belief, "belief")
    n = belief.shape[0]
    transition = as_matrix(transition, "transition", (n, n))
    if np.any(transition < 0):
        raise ValueError("transition must be non-negative (entries are probabilities)")
    column_sums = transition.sum(axis=0)
    worst = int(np.argmax(np.abs(column_sums - 1.0)))
    if abs(column_sums[worst] - 1.0) > _SUM_ATOL:
        raise ValueError(f"transition columns must sum to 1 (transition[i, j] = "
                         f"p(x_k = i | x_k-1 = j)); column {worst} sums to "
                         f"{column_sums[worst]:.12g}")
    return transition @ belief


def circular_motion_model(n, step_probs):
    """Transition matrix for a robot moving along a circular corridor of n cells.

    From cell j the robot ends in cell ``(j + offset) % n`` with probability
    ``step_probs[offset]``, so ``transition[(j + offset) % n, j] += step_probs[offset]``.
    Offsets may be negative (moving backwards); offsets equal modulo n add up.

    Parameters
    ----------
    n : int
        Number of cells, at least 1.
    step_probs : dict of {int: float}
        Probability of each step offset, for example ``{0: 0.1, 1: 0.8, 2: 0.1}``.
        Non-negative, summing to one.

    Returns
    -------
    ndarray, shape (n, n)
        ``transition[i, j]`` = :math:`p(x_k = i \\mid x_{k-1} = j)`, columns summing to one.

    Raises
    ------
    ValueError
        If ``n`` is not a positive integer, or ``step_probs`` is not a non-empty dict of
        integer offsets to non-negative probabilities summing to one.
    """
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer number of cells, got {n!r}")
    if not isinstance(step_probs, dict) or not step_probs:
        raise ValueError("step_probs must be a non-empty dict {offset: probability}, "
                         f"got {step_probs!r}")
    total = 0.0
    for offset, prob in step_probs.items():
        if isinstance(offset, (bool, np.bool_)) or not isinstance(offset, (int, np.integer)):
            raise ValueError(f"step_probs keys must be integer offsets, got {offset!r}")
        total += as_scalar(prob, f"step_probs[{offset}]", allow_zero=True)
    if abs(total - 1.0) > _SUM_ATOL:
        raise ValueError(f"step_probs probabilities must sum to 1, got {total:.12g}")

    n = int(n)
    transition = np.zeros((n, n))
    cells = np.arange(n)
    for offset, prob in step_probs.items():
        # np.add.at accumulates, so offsets that coincide modulo n add up
        np.add.at(transition, ((cells + int(offset)) % n, cells), float(prob))
    return transition
