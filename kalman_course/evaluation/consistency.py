"""Consistency tests of a filter: NEES/NIS records against their chi-square bounds, and gating.

A filter is *consistent* when its errors are as large as its covariance says: the NEES
:math:`e^T P^{-1} e` (e = estimate − truth) and the NIS :math:`\\nu^T S^{-1} \\nu` are then
chi-square with as many degrees of freedom as the vector has components. The statistics
themselves and their chi-square quantiles are :mod:`kalman_course.evaluation.metrics`;
this module turns them into answers:

- :func:`summarise` — mean of a NEES/NIS record, its two-sided bounds and the share of
  single values inside the per-step bounds, as one :class:`Consistency` record;
- :func:`verdict` — "consistent", "overconfident" (P or S too small) or "underconfident";
- :func:`gate_threshold` and :func:`gate` — the chi-square innovation gate;
- :func:`correlation_time` and :func:`average_band` — the interval of a NEES/NIS record
  averaged over time (correlated samples) and over independent runs, as one
  :class:`AverageBand`;
- :func:`innovation_whiteness` — the autocorrelation of the whitened innovations and the
  Ljung–Box portmanteau test, as one :class:`Whiteness` record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import (SYMMETRY_RTOL, as_covariance, as_real_array, as_scalar,
                                           as_vector)
from kalman_course.evaluation import metrics

__all__ = ["Consistency", "summarise", "verdict", "VERDICTS", "gate_threshold", "gate",
           "correlation_time", "AverageBand", "average_band", "Whiteness", "innovation_whiteness"]

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
    v = as_real_array(values, "values", allow_empty=True).ravel()
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


# ---------------------------------------------------------------------------------------
# Averages over time: correlated samples
# ---------------------------------------------------------------------------------------

def _runs_by_time(values, name: str) -> np.ndarray:
    """``values`` as a finite float array of shape (n_runs, K): one row per independent run."""
    v = np.array(as_real_array(values, name, allow_empty=True))
    if v.ndim == 1:
        v = v[None, :]
    if v.ndim != 2 or v.shape[1] < 1 or v.shape[0] < 1:
        raise ValueError(f"{name} must have shape (K,) for one run or (n_runs, K), got {np.shape(values)}")
    if not np.isfinite(v).all():
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return v


def correlation_time(values) -> float:
    """Integrated autocorrelation time τ = 1 + 2 Σ_k ρ_k of a record, pooled over runs.

    K correlated samples of a stationary sequence carry as much information about its mean
    as K / τ independent ones. The autocorrelations ρ_k are estimated from the record
    itself: each run is centred on its own mean, the lag products are summed over all runs
    and divided by the summed squares. The sum over lags stops at the first pair
    ρ_{2j} + ρ_{2j+1} that is not positive (Geyer's initial positive sequence), where the
    estimates are no longer distinguishable from noise. τ is clipped to [1, K]: a record
    is never worth more than its K samples, nor fewer than one.

    Parameters
    ----------
    values : array_like, shape (K,) or (n_runs, K)
        The record over time; rows are independent runs of the same length.

    Returns
    -------
    float
        τ ≥ 1 (1 for white samples).

    Raises
    ------
    ValueError
        If ``values`` is not a finite 1-D or 2-D array of numbers.
    """
    v = _runs_by_time(values, "values")
    K = v.shape[1]
    c = v - v.mean(axis=1, keepdims=True)
    c0 = float(np.sum(c * c))
    if K < 2 or c0 == 0.0:
        return 1.0

    def rho(k: int) -> float:
        return float(np.sum(c[:, :K - k] * c[:, k:])) / c0 if k < K else 0.0

    tau, j = -1.0, 0                       # τ = −1 + 2 Σ_j (ρ_2j + ρ_2j+1), with ρ_0 = 1
    while 2 * j + 1 < K:
        pair = (1.0 if j == 0 else rho(2 * j)) + rho(2 * j + 1)
        if pair <= 0.0:
            break
        tau += 2.0 * pair
        j += 1
    return float(min(max(tau, 1.0), K))


@dataclass(frozen=True)
class AverageBand:
    """A NEES/NIS record averaged over time and runs, with the interval that average lies in.

    Attributes
    ----------
    mean : float
        The average of every value of the record.
    lo, hi : float
        Two-sided interval of that average for a consistent filter (see :func:`average_band`).
    dof : int
        Degrees of freedom of one value.
    n_runs, n_steps : int
        Independent runs averaged, and values per run.
    correlation_time : float
        τ of :func:`correlation_time`, in steps.
    n_effective : float
        n_runs · n_steps / τ: how many independent χ²(dof) values the average is worth.
    confidence : float
        Mass of the interval.
    """

    mean: float
    lo: float
    hi: float
    dof: int
    n_runs: int
    n_steps: int
    correlation_time: float
    n_effective: float
    confidence: float

    @property
    def verdict(self) -> str:
        """"overconfident" above the interval, "underconfident" below it, else "consistent"."""
        if self.mean > self.hi:
            return "overconfident"
        if self.mean < self.lo:
            return "underconfident"
        return "consistent"


def average_band(values, dof: int, confidence: float = 0.95) -> AverageBand:
    """The interval of a NEES/NIS record averaged over its time steps and over runs.

    The average of N *independent* χ²(dof) values, times N, is χ²(N·dof)
    (:func:`kalman_course.evaluation.metrics.chi2_bounds`). Independent runs give
    independent values, but the steps of one run do not: a NEES carries the estimation
    error from step to step, so its samples are correlated and the band of N independent
    values would be far too narrow. This function counts each run as n_steps / τ
    independent values, with τ the record's own :func:`correlation_time`, and uses the
    χ² interval for that effective count n_eff (a scaled χ²(dof·n_eff) / n_eff, which has the
    average's mean dof and variance 2·dof / n_eff; n_eff need not be an integer). For a
    white record (τ = 1) this is exactly ``chi2_bounds(dof, n_runs * n_steps)``.

    τ is estimated from the same record, which makes the interval a little too narrow for
    short runs (coverage about 0.90 instead of 0.95 at some 20 effective values per run,
    measured by simulation in ``tests/test_consistency.py``); it improves as runs get
    longer or more runs are pooled.

    Parameters
    ----------
    values : array_like, shape (K,) or (n_runs, K)
        NEES or NIS over time, one row per independent run (one row for a single run).
    dof : int
        Degrees of freedom of one value, >= 1.
    confidence : float
        Mass of the two-sided interval, in (0, 1).

    Returns
    -------
    AverageBand

    Raises
    ------
    ValueError
        If ``values`` is not a finite (K,) or (n_runs, K) array, or ``dof`` or
        ``confidence`` is out of range.

    Examples
    --------
    >>> import numpy as np
    >>> band = average_band(np.random.default_rng(0).chisquare(6, size=(4, 200)), 6)
    >>> band.verdict
    'consistent'
    """
    dof, confidence = _dof(dof), _confidence(confidence)
    v = _runs_by_time(values, "values")
    n_runs, K = v.shape
    tau = correlation_time(v)
    n_eff = n_runs * K / tau
    lo = metrics.chi2_ppf((1.0 - confidence) / 2.0, dof * n_eff) / n_eff
    hi = metrics.chi2_ppf((1.0 + confidence) / 2.0, dof * n_eff) / n_eff
    return AverageBand(float(v.mean()), float(lo), float(hi), dof, n_runs, K, tau, float(n_eff), confidence)


# ---------------------------------------------------------------------------------------
# Whiteness of the innovations
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Whiteness:
    """Autocorrelation of a filter's whitened innovations and its portmanteau test.

    Attributes
    ----------
    lags : numpy.ndarray of int, shape (L,)
        1 … L.
    autocorrelation : numpy.ndarray, shape (m, L)
        Normalised autocorrelation of each whitened innovation component at each lag.
    band : float
        z / √N: a white sequence's autocorrelation at one lag lies inside ±band with
        probability ``confidence``.
    statistic : float
        Ljung–Box Q = N (N + 2) Σ_k ρ_k² / (N − k), summed over the m components.
    threshold : float
        The ``confidence`` quantile of χ²(m·L), the distribution of Q for white innovations.
    n_samples : int
        N, innovations used.
    confidence : float
    """

    lags: np.ndarray
    autocorrelation: np.ndarray
    band: float
    statistic: float
    threshold: float
    n_samples: int
    confidence: float

    @property
    def white(self) -> bool:
        """True when the portmanteau statistic is at most its threshold."""
        return bool(self.statistic <= self.threshold)

    @property
    def share_outside(self) -> float:
        """Share of the m·L autocorrelations outside ±band (about 1 − confidence if white)."""
        return float(np.mean(np.abs(self.autocorrelation) > self.band))


def innovation_whiteness(innovation, S, max_lag: int = 10, confidence: float = 0.95) -> Whiteness:
    """Test whether a filter's innovations are white, without the truth.

    A consistent, optimal filter's innovations ν_k are independent N(0, S_k): each new
    observation brings only what the filter could not predict. Errors the filter does not
    model (a coloured sensor noise, say) leave a part it could have predicted, which shows
    as correlation between innovations at different steps. Each ν_k is first whitened,
    u_k = L_k⁻¹ ν_k with S_k = L_k L_kᵀ (Cholesky), so that its m components are independent
    N(0, 1); then, per component, the normalised autocorrelation at lags 1 … L (centred on
    the component's mean) is compared with the band ±z/√N of a white sequence, and the
    Ljung–Box statistic, summed over the components, with the χ²(m·L) quantile.

    Parameters
    ----------
    innovation : array_like, shape (N, m)
        Innovations in time order, at equally spaced updates (a lag is one update).
    S : array_like, shape (N, m, m)
        Their covariances, symmetric positive definite.
    max_lag : int
        L, the largest lag tested, 1 <= L < N.
    confidence : float
        Mass of the band and of the test's acceptance region, in (0, 1).

    Returns
    -------
    Whiteness

    Raises
    ------
    ValueError
        For shapes that do not match, values that are not finite, an S that is not
        positive definite, or ``max_lag`` or ``confidence`` out of range.
    """
    confidence = _confidence(confidence)
    nu = np.array(as_real_array(innovation, "innovation"))
    S_arr = np.array(as_real_array(S, "S"))
    if nu.ndim != 2 or S_arr.shape != (nu.shape[0], nu.shape[1], nu.shape[1]):
        raise ValueError(f"need innovation (N, m) and S (N, m, m); got innovation {nu.shape}, S {S_arr.shape}")
    if not (np.isfinite(nu).all() and np.isfinite(S_arr).all()):
        raise ValueError("innovation and S must be finite (no NaN or inf)")
    asym = np.abs(S_arr - np.swapaxes(S_arr, 1, 2)).max(axis=(1, 2))
    unsymmetric = asym > SYMMETRY_RTOL * np.abs(S_arr).max(axis=(1, 2))      # (0 > 0 for a zero S_k)
    if unsymmetric.any():
        k = int(np.argmax(unsymmetric))
        raise ValueError(f"S must be symmetric at every step; S[{k}] is not (max |S - S.T| = {asym[k]:.3g})")
    N, m = nu.shape
    L = _dof(max_lag, "max_lag")
    if L >= N:
        raise ValueError(f"max_lag must be smaller than the number of innovations {N}, got {max_lag!r}")
    try:
        chol = np.linalg.cholesky(S_arr)
    except np.linalg.LinAlgError:
        raise ValueError("S must be positive definite at every step") from None
    u = np.linalg.solve(chol, nu[:, :, None])[:, :, 0]
    c = u - u.mean(axis=0)
    c0 = np.sum(c * c, axis=0)
    if np.any(c0 == 0.0):
        raise ValueError("a whitened innovation component is constant: nothing to test")
    lags = np.arange(1, L + 1)
    acf = np.array([np.sum(c[:N - k] * c[k:], axis=0) / c0 for k in lags]).T      # (m, L)
    statistic = float(N * (N + 2) * np.sum(acf ** 2 / (N - lags)))
    band = float(np.sqrt(metrics.chi2_ppf(confidence, 1)) / np.sqrt(N))
    threshold = float(metrics.chi2_ppf(confidence, m * L))
    return Whiteness(lags, acf, band, statistic, threshold, N, confidence)
