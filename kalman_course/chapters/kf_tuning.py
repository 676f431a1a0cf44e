"""Chapter 03: tuning a linear Kalman filter from its innovations alone, without the truth.

The innovations of the optimal filter are white with covariance S. Two statistics follow,
and they answer different questions. The mean NIS says whether S has the right *size*:
scaling Q and R by the same factor leaves the gain, and so the estimate, unchanged and
divides the NIS by that factor. The innovations' autocorrelation says whether the *gain*
is right: a gain that weighs prediction and measurement in the wrong ratio leaves
something predictable in the innovations, which then correlate with their own past.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_covariance, as_int, as_matrix, as_scalar
from kalman_course.evaluation import metrics
from kalman_course.evaluation.consistency import innovation_whiteness
from kalman_course.filters import kf

__all__ = ["TuningRow", "innovation_tuning", "sigma_for_unit_nis"]


@dataclass(frozen=True)
class TuningRow:
    """One (Q, R) setting of :func:`innovation_tuning`, judged from the innovations and, for comparison, the truth.

    Attributes
    ----------
    Q, R : numpy.ndarray
        The filter's process noise (state space, n × n) and measurement noise (m × m).
    nis : float
        NIS averaged over the runs and the steps after the transient.
    nis_band : (float, float)
        95 % interval of that average for white innovations, ``chi2_bounds(m, n_values)``.
    whiteness : tuple of Whiteness
        :func:`~kalman_course.evaluation.consistency.innovation_whiteness` of each run.
    position_rmse : float
        RMSE of the first state component against the simulated truth (not used to tune).
    """

    Q: np.ndarray
    R: np.ndarray
    nis: float
    nis_band: tuple
    whiteness: tuple
    position_rmse: float

    @property
    def n_white(self) -> int:
        """How many runs' innovations pass the whiteness test."""
        return sum(w.white for w in self.whiteness)

    @property
    def nis_verdict(self) -> str:
        """The mean NIS against ``nis_band``: "overconfident", "underconfident" or "consistent"."""
        lo, hi = self.nis_band
        return "overconfident" if self.nis > hi else "underconfident" if self.nis < lo else "consistent"


def _as_runs(runs) -> list:
    """``runs`` as a non-empty list of simulated runs (each with ``z`` and ``x``); else a ValueError."""
    if isinstance(runs, (str, bytes)) or not np.iterable(runs):
        raise ValueError(f"runs must be a sequence of simulated runs (CVTarget: z, x), got {type(runs).__name__}")
    runs = list(runs)
    if not runs:
        raise ValueError("runs must hold at least one simulated run")
    for i, run in enumerate(runs):
        if not (hasattr(run, "z") and hasattr(run, "x")):
            raise ValueError(f"runs[{i}] must be a simulated run with measurements z and truth x (a CVTarget), "
                             f"got {type(run).__name__}")
    return runs


def innovation_tuning(runs, x0, P0, F, G, Q, R, *, skip: int = 10, max_lag: int = 5) -> TuningRow:
    """Filter every simulated run with one (Q, R) and test its innovations.

    Parameters
    ----------
    runs : sequence of CVTarget
        Simulated runs (``run.z`` measurements (N, m), ``run.x`` truth (N, n)); each one is
        filtered from the same prior.
    x0 : array_like, shape (n,)
        Prior mean at step 0.
    P0 : array_like, shape (n, n)
        Prior covariance at step 0.
    F, G : array_like
        Motion (n, n) and observation (m, n) matrices.
    Q : array_like, shape (n, n)
        Process noise in state space (B Q Bᵀ, e.g. ``symbolic.cv_process_noise``).
    R : array_like, shape (m, m)
        Measurement noise.
    skip : int
        Steps dropped at the start of each run (the transient from P0).
    max_lag : int
        Largest lag of the whiteness test, in steps.

    Returns
    -------
    TuningRow
    """
    runs = _as_runs(runs)
    skip = as_int(skip, "skip", minimum=0)
    G = as_matrix(G, "G")
    Q = as_covariance(Q, "Q", psd=True)
    R = as_covariance(R, "R", psd=True)
    if R.shape != (G.shape[0], G.shape[0]):
        raise ValueError(f"R must have shape ({G.shape[0]}, {G.shape[0]}), one row and column per row of G "
                         f"{G.shape}, got {R.shape}")
    nis, tests, estimates, truths = [], [], [], []
    for run in runs:
        h = kf.run_kf(x0, P0, F, Q, G, R, run.z)
        nu, S = np.asarray(h.innovation)[skip:], np.asarray(h.S)[skip:]
        nis.append(metrics.normalised_squared(nu, S, "innovation", "S"))
        tests.append(innovation_whiteness(nu, S, max_lag=max_lag))
        estimates.append(h.x_hat[skip:, 0])
        truths.append(run.x[skip:, 0])
    nis = np.concatenate(nis)
    band = metrics.chi2_bounds(R.shape[0], len(nis))
    return TuningRow(Q, R, float(nis.mean()), band, tuple(tests),
                     float(metrics.rmse(np.concatenate(estimates), np.concatenate(truths), axis=None)))


def sigma_for_unit_nis(runs, x0, P0, F, G, Q, *, lo: float = 1e-2, hi: float = 1e2, skip: int = 10,
                       iterations: int = 30) -> float:
    """The measurement σ (R = σ² I) that makes the mean NIS equal its dof m, for a given Q.

    What tuning by the NIS alone would pick, with Q fixed: the mean NIS falls as σ grows
    (a larger R, a larger S), so a bisection on log σ finds it.

    Parameters
    ----------
    runs, x0, P0, F, G, Q, skip
        As for :func:`innovation_tuning`.
    lo, hi : float
        Bracket of σ, 0 < lo < hi; the NIS must be above m at ``lo`` and below it at ``hi``.
    iterations : int
        Bisection steps (each halves the bracket in log σ).

    Returns
    -------
    float
        σ, in the units of the measurements.
    """
    lo, hi = as_scalar(lo, "lo"), as_scalar(hi, "hi")
    if not lo < hi:
        raise ValueError(f"need 0 < lo < hi, got lo={lo!r}, hi={hi!r}")
    iterations = as_int(iterations, "iterations", minimum=1)
    runs = _as_runs(runs)
    m = as_matrix(G, "G").shape[0]

    def excess(sigma):
        return innovation_tuning(runs, x0, P0, F, G, Q, sigma**2 * np.eye(m), skip=skip).nis - m

    if not (excess(lo) > 0.0 > excess(hi)):
        raise ValueError(f"the mean NIS does not cross {m} between sigma {lo:g} and {hi:g}: widen lo, hi")
    log_lo, log_hi = np.log(lo), np.log(hi)
    for _ in range(iterations):
        mid = 0.5 * (log_lo + log_hi)
        if excess(np.exp(mid)) > 0.0:
            log_lo = mid
        else:
            log_hi = mid
    return float(np.exp(0.5 * (log_lo + log_hi)))
