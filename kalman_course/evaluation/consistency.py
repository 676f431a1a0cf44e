"""Consistency tests of a filter: NEES/NIS records against their chi-square bounds, and gating.

A filter is *consistent* when its errors are as large as its covariance says: the NEES
:math:`e^T P^{-1} e` (e = estimate − truth) and the NIS :math:`\\nu^T S^{-1} \\nu` are then
chi-square with as many degrees of freedom as the vector has components. The statistics
themselves and their chi-square quantiles are :mod:`kalman_course.evaluation.metrics`;
this module turns them into answers:

- :func:`summarise` — mean of a NEES/NIS record, its two-sided bounds and the share of
  single values inside the per-step bounds, as one :class:`Consistency` record;
- :func:`verdict` — "consistent", "overconfident" (P or S too small) or "underconfident";
- :func:`gate_threshold` and :func:`gate` — the chi-square innovation gate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_covariance, as_scalar, as_vector
from kalman_course.evaluation import metrics

__all__ = ["Consistency", "summarise", "verdict", "VERDICTS", "gate_threshold", "gate"]

#: The three answers of :func:`verdict`.
VERDICTS = ("consistent", "overconfident", "underconfident")


def _confidence(confidence) -> float:
    value = as_scalar(confidence, "confidence")
    if not 0.0 < value < 1.0:
        raise ValueError(f"confidence must be a probability in (0, 1), got {confidence!r}")
    return value


def _dof(dof, name: str = "dof") -> int:
    if isinstance(dof, bool) or not isinstance(dof, (int, np.integer)) or dof < 1:
        raise ValueError(f"{name} must be a positive integer, got {dof!r}")
    return int(dof)


@dataclass(frozen=True)
class Consistency:
    """A NEES or NIS record summarised against its chi-square bounds.

    Attributes
    ----------
    dof : int
        Degrees of freedom of one value.
    n_runs : int
        How many independent values each averaged value is made of (1 for a single run).
    mean : float
        Mean of the record (NaN entries skipped).
    mean_lo, mean_hi : float
        Two-sided bounds for that mean, treating every value as independent
        (``chi2_bounds(dof, n_values * n_runs)``). Only for white sequences such as the NIS
        of one run is this the right test; a NEES record over time is correlated.
    lo, hi : float
        Two-sided bounds for one (run-averaged) value, ``chi2_bounds(dof, n_runs)``.
    share_inside : float
        Share of the values inside [lo, hi]; about ``confidence`` for a consistent filter.
    confidence : float
        Mass of the two-sided intervals.
    """

    dof: int
    n_runs: int
    mean: float
    mean_lo: float
    mean_hi: float
    lo: float
    hi: float
    share_inside: float
    confidence: float


def summarise(values, dof: int, n_runs: int = 1, confidence: float = 0.95) -> Consistency:
    """Summarise NEES/NIS ``values`` (any shape; NaN skipped) of ``dof`` degrees of freedom.

    Parameters
    ----------
    values : array_like
        One value per step, each already averaged over ``n_runs`` runs if n_runs > 1.
    dof : int
        Dimension of the vector each value was computed from, >= 1.
    n_runs : int
        Number of runs averaged into each value, >= 1.
    confidence : float
        Mass of the two-sided intervals, in (0, 1).

    Returns
    -------
    Consistency

    Raises
    ------
    ValueError
        If ``values`` holds no number other than NaN, or holds inf; or if ``dof``,
        ``n_runs`` or ``confidence`` is out of range.
    """
    dof, n_runs, confidence = _dof(dof), _dof(n_runs, "n_runs"), _confidence(confidence)
    try:
        v = np.asarray(values, dtype=float).ravel()
    except (TypeError, ValueError):
        raise ValueError(f"values must be an array of numbers, got {type(values).__name__}") from None
    v = v[~np.isnan(v)]
    if v.size == 0:
        raise ValueError("values must contain at least one non-NaN value")
    if np.isinf(v).any():
        raise ValueError("values must not contain inf")
    lo, hi = metrics.chi2_bounds(dof, n_runs, confidence)
    mean_lo, mean_hi = metrics.chi2_bounds(dof, n_runs * v.size, confidence)
    return Consistency(dof, n_runs, float(np.mean(v)), mean_lo, mean_hi, lo, hi,
                       metrics.share_inside(v, lo, hi), confidence)


def verdict(values, dof: int, confidence: float = 0.95) -> str:
    """Judge a white NIS (or independent NEES) record by its mean and the two-sided bounds.

    The mean of N independent χ²(dof) values, times N, is χ²(N·dof). Above the upper bound
    the errors are larger than the filter believes: it is **overconfident** (P or S too
    small: raise Q or R). Below the lower bound it is **underconfident**. Inside:
    **consistent**.

    Parameters
    ----------
    values : array_like
        The record (any shape; NaN skipped).
    dof : int
        Degrees of freedom of one value.
    confidence : float
        Mass of the two-sided interval of the mean.

    Returns
    -------
    str
        One of :data:`VERDICTS`.
    """
    s = summarise(values, dof, 1, confidence)
    if s.mean > s.mean_hi:
        return "overconfident"
    if s.mean < s.mean_lo:
        return "underconfident"
    return "consistent"


def gate_threshold(dof: int, confidence: float = 0.99) -> float:
    """The NIS above which an innovation of ``dof`` components is rejected: the χ²_dof quantile.

    Parameters
    ----------
    dof : int
        Number of components of the innovation, >= 1.
    confidence : float
        Probability that a consistent filter accepts a correct observation, in (0, 1).
    """
    return metrics.chi2_ppf(_confidence(confidence), _dof(dof))


def gate(innovation, S, confidence: float = 0.99) -> bool:
    """Chi-square gate: True (accept) when the NIS νᵀ S⁻¹ ν is at most the χ²_m quantile.

    Parameters
    ----------
    innovation : array_like, shape (m,)
        ν = y − g(x̌).
    S : array_like, shape (m, m)
        Innovation covariance, symmetric positive definite.
    confidence : float
        Probability that a consistent filter accepts a correct observation.

    Returns
    -------
    bool
    """
    innovation = as_vector(innovation, "innovation")
    S = as_covariance(S, "S", innovation.shape[0], positive_definite=True)
    return bool(metrics.nis(innovation, S) <= gate_threshold(innovation.shape[0], confidence))
