"""The numbers behind the course's intuition figures (chapters 01, 02, 03, 05 and 06).

Each function here computes what one picture shows, with the filters of the layers below
(no filter equation is written again here):

- chapter 01: :func:`truncated_normal_moments`, the moments of a Gaussian prior cut off
  by the ends of a grid;
- chapter 02: :func:`correlated_pair_covariance` and :func:`scalar_conditioning` (two
  correlated scalars conditioned by hand, each step proved by SymPy), :func:`window_slice`
  (their Monte Carlo check, :class:`WindowSlice`), :func:`ellipse_highest_point` (where the
  regression line meets an ellipse), :func:`check_chain` and :class:`Folded` (a hand-written
  chain of steps proved by SymPy, SymPy's own output folded away);
  :func:`information_trial`, one linear-Gaussian update repeated over runs and seeds,
  scored against truths the estimator does not see (:class:`InformationTrial`);
- chapter 03: :func:`kf_1d_table`, a scalar Kalman filter whose every number a learner
  can check by hand (:class:`KF1DTable`); :func:`scalar_gain`, the gain as a function of
  the prior and measurement variances; :func:`steady_state`, the covariance and gain a
  time-invariant filter settles to (:class:`SteadyState`);
- chapter 05: :func:`radar_cloud`, a Gaussian position cloud pushed through the radar's
  range and bearing next to the EKF's linearisation (:class:`RadarCloud`), and
  :func:`cross_range_covariance`, a cloud stretched across the radar's line of sight;
- chapter 06: :func:`map_cost` (the cost one update minimises),
  :func:`gauss_newton_cost` (its quadratic model at an operating point),
  :func:`cost_on_plane` (either one over a grid) and :func:`iekf_iterates` (the points the
  iterated EKF visits).

The figures themselves are drawn by :mod:`kalman_course.plotting.intuition`.
"""

from __future__ import annotations

import functools
import html
from dataclasses import dataclass
from typing import Callable

import numpy as np
import sympy as sp

from kalman_course import symbolic
from kalman_course.core.angles import wrap_angle
from kalman_course.core.gaussians import linear_map
from kalman_course.core.validation import (as_covariance, as_matrix, as_real_array, as_scalar, as_seed, as_seeds,
                                           as_vector)
from kalman_course.filters.ekf import iekf_update
from kalman_course.filters.kf import innovation_covariance, kf_gain, kf_predict, kf_update, run_kf
from kalman_course.symbolic.equations import Derivation, Equation

__all__ = ["KF1DTable", "kf_1d_table", "scalar_gain", "SteadyState", "steady_state", "RadarCloud",
           "cross_range_covariance", "radar_cloud", "map_cost", "gauss_newton_cost", "cost_on_plane", "iekf_iterates",
           "truncated_normal_moments", "InformationTrial", "information_trial",
           "correlated_pair_covariance", "scalar_conditioning", "WindowSlice", "window_slice",
           "ellipse_highest_point", "ChainCheck", "check_chain", "Folded"]


# --------------------------------------------------------------------------------------
# chapter 03: a Kalman filter in one dimension, by hand
# --------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class KF1DTable:
    """Every number of a scalar Kalman filter, one row per step.

    The model is a random walk seen directly: :math:`x_k = x_{k-1} + w_k`,
    :math:`w_k \\sim \\mathcal N(0, q)`, and :math:`y_k = x_k + n_k`,
    :math:`n_k \\sim \\mathcal N(0, r)`.

    Attributes
    ----------
    x_check, P_check : ndarray, shape (N,)
        Prior mean and variance of each step (step 0's are the given prior).
    y : ndarray, shape (N,)
        The measurements (NaN: none at that step).
    K : ndarray, shape (N,)
        The gain (NaN where there was no measurement).
    x_hat, P_hat : ndarray, shape (N,)
        Posterior mean and variance.
    q, r : float
        Process- and measurement-noise variances.
    """

    x_check: np.ndarray
    P_check: np.ndarray
    y: np.ndarray
    K: np.ndarray
    x_hat: np.ndarray
    P_hat: np.ndarray
    q: float
    r: float

    def __len__(self) -> int:
        return int(self.y.shape[0])

    def to_text(self, digits: int = 3) -> str:
        """The table as fixed-width text, one line per step."""
        head = ("k", "prior mean x̌", "prior var P̌", "measurement y", "gain K", "post. mean x̂", "post. var P̂")
        widths = [3] + [max(len(h), digits + 6) for h in head[1:]]
        lines = ["  ".join(h.rjust(w) for h, w in zip(head, widths))]
        for k in range(len(self)):
            cells = [self.x_check[k], self.P_check[k], self.y[k], self.K[k], self.x_hat[k], self.P_hat[k]]
            text = ["—" if np.isnan(v) else f"{v:.{digits}f}" for v in cells]
            lines.append("  ".join([str(k).rjust(widths[0])] + [c.rjust(w) for c, w in zip(text, widths[1:])]))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.to_text()


def kf_1d_table(x0, P0, ys, *, q, r) -> KF1DTable:
    """Run a scalar Kalman filter (``kf.run_kf`` with 1 × 1 matrices) and tabulate it.

    Parameters
    ----------
    x0 : float
        Prior mean at step 0, :math:`\\check x_0`.
    P0 : float
        Prior variance at step 0, :math:`\\check P_0` (> 0).
    ys : array_like, shape (N,)
        One measurement per step; NaN for a step without one.
    q : float
        Process-noise variance per step (>= 0): the random walk's spread.
    r : float
        Measurement-noise variance (> 0).

    Returns
    -------
    KF1DTable

    Raises
    ------
    ValueError
        Naming the argument: a non-finite ``x0``, a ``P0`` or ``r`` that is not positive,
        a negative ``q``, ``ys`` that is not a non-empty 1-D array.
    """
    x0 = as_vector([x0], "x0", 1)
    P0 = as_scalar(P0, "P0")
    q = as_scalar(q, "q", allow_zero=True)
    r = as_scalar(r, "r")
    ys = as_real_array(ys, "ys")
    if ys.ndim != 1 or ys.size == 0:
        raise ValueError(f"ys must be a non-empty 1-D array of measurements, got shape {ys.shape}")
    one = np.ones((1, 1))
    hist = run_kf(x0, P0 * one, one, q * one, one, r * one, ys[:, None])
    return KF1DTable(x_check=hist.x_check[:, 0], P_check=hist.P_check[:, 0, 0], y=ys.copy(), K=hist.K[:, 0, 0],
                     x_hat=hist.x_hat[:, 0], P_hat=hist.P_hat[:, 0, 0], q=q, r=r)


def scalar_gain(P_check, R, g=1.0):
    """The Kalman gain of a scalar state seen by a scalar measurement, y = g x + n.

    :math:`K = \\check P g / (g^2 \\check P + R)`, computed by ``kf.kf_gain`` for each pair.

    Parameters
    ----------
    P_check : float or array_like
        Prior variance(s), >= 0.
    R : float or array_like
        Measurement-noise variance(s), > 0; broadcast against ``P_check``.
    g : float
        The observation coefficient (non-zero).

    Returns
    -------
    float or ndarray
        The gain, of the broadcast shape (a float for scalar inputs).
    """
    P = as_real_array(P_check, "P_check")
    Rv = as_real_array(R, "R")
    g = float(as_vector([g], "g", 1)[0])
    if g == 0.0:
        raise ValueError("g must be non-zero (a measurement that sees the state)")
    if np.any(P < 0):
        raise ValueError(f"P_check must be >= 0, min is {P.min():.3g}")
    if np.any(Rv <= 0):
        raise ValueError(f"R must be > 0, min is {Rv.min():.3g}")
    try:
        P, Rv = np.broadcast_arrays(P, Rv)
    except ValueError:
        raise ValueError(f"P_check {P.shape} and R {Rv.shape} do not broadcast") from None
    G = np.array([[g]])
    out = np.empty(P.shape)
    for i in np.ndindex(P.shape):
        Pk = np.array([[P[i]]])
        out[i] = kf_gain(Pk, G, innovation_covariance(Pk, G, np.array([[Rv[i]]])))[0, 0]
    return float(out) if out.ndim == 0 else out


@dataclass(frozen=True, eq=False)
class SteadyState:
    """Where the covariance recursion of a time-invariant Kalman filter settles.

    Attributes
    ----------
    P_check : ndarray, shape (n, n)
        Steady-state prior covariance, the fixed point of the Riccati recursion.
    P_hat : ndarray, shape (n, n)
        Steady-state posterior covariance.
    K : ndarray, shape (n, m)
        Steady-state gain.
    steps : int
        Predict–update cycles it took from the start covariance.
    """

    P_check: np.ndarray
    P_hat: np.ndarray
    K: np.ndarray
    steps: int


def _check_rows_of_G(R, name: str, G: np.ndarray) -> None:
    """Raise a ValueError naming ``name`` and G unless the covariance R is (m, m) for G's m rows."""
    arr = as_covariance(R, name)
    m = G.shape[0]
    if arr.shape != (m, m):
        raise ValueError(f"{name} must have shape ({m}, {m}), one row and column per row of G {G.shape}, "
                         f"got {arr.shape}")


def _seed_list(seeds) -> np.ndarray:
    """``seeds`` (a non-empty sequence of non-negative ints) as an int array; else a ValueError naming it."""
    return np.array(as_seeds(seeds), dtype=int)


def steady_state(F, Q, G, R, *, B=None, P0=None, rtol=1e-12, max_steps=100_000) -> SteadyState:
    """Iterate ``kf_update`` and ``kf_predict`` until the prior covariance stops changing.

    P̌ and K of a Kalman filter do not depend on the measurements, so the recursion
    :math:`\\check P \\to F(\\check P - \\check P G^T S^{-1} G \\check P)F^T + B Q B^T` can be
    run on its own. For a detectable, stabilisable model it converges to the same fixed
    point from any start.

    Parameters
    ----------
    F, Q, G, R, B
        The model, as for ``kf.run_kf``.
    P0 : array_like, shape (n, n), optional
        Start covariance (default the identity).
    rtol : float
        Stop when no entry of P̌ changes by more than ``rtol`` times its largest entry.
    max_steps : int
        Give up (ValueError) after this many cycles.

    Returns
    -------
    SteadyState

    Raises
    ------
    ValueError
        For invalid model matrices (as ``kf``), or if the recursion has not settled after
        ``max_steps`` cycles (for example a model whose unobserved part grows).
    """
    F = as_matrix(F, "F")
    n = F.shape[0]
    F = as_matrix(F, "F", (n, n))
    G = as_matrix(G, "G", (None, n))
    _check_rows_of_G(R, "R", G)
    P = np.eye(n) if P0 is None else as_covariance(P0, "P0", n, psd=True)
    rtol = as_scalar(rtol, "rtol")
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
        raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    x, y = np.zeros(n), np.zeros(G.shape[0])
    for step in range(1, int(max_steps) + 1):
        update = kf_update(x, P, y, G, R)
        _, P_next = kf_predict(x, update.P_hat, F, Q, B)
        if np.max(np.abs(P_next - P)) <= rtol * np.max(np.abs(P_next)):
            final = kf_update(x, P_next, y, G, R)
            return SteadyState(P_check=P_next, P_hat=final.P_hat, K=final.K, steps=step)
        P = P_next
    raise ValueError(f"the covariance did not settle within max_steps={max_steps} cycles")


# --------------------------------------------------------------------------------------
# chapter 05: a Gaussian cloud through the radar, and its linearisation
# --------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class RadarCloud:
    """A Gaussian position cloud seen by a radar at the origin, exactly and linearised.

    Attributes
    ----------
    mean_xy : ndarray, shape (2,)
        Mean position μ, m.
    cov_xy : ndarray, shape (2, 2)
        Position covariance P, m².
    samples_xy : ndarray, shape (N, 2)
        Positions drawn from N(μ, P).
    samples_polar : ndarray, shape (N, 2)
        Their [ρ, φ] from the radar model (bearings unwrapped around φ(μ)).
    lin_mean : ndarray, shape (2,)
        The EKF's predicted measurement g(μ).
    lin_cov : ndarray, shape (2, 2)
        The EKF's covariance of it, G P Gᵀ, with G the radar Jacobian at μ.
    sample_mean, sample_cov : ndarray, shapes (2,), (2, 2)
        Mean and covariance of ``samples_polar``: what the linearisation should match.
    inside_share : float
        Share of ``samples_polar`` inside the linearised ``n_sigma`` ellipse.
    expected_share : float
        That share for an exactly Gaussian [ρ, φ]: 1 − exp(−n_sigma²/2).
    n_sigma : float
        Size of the ellipse.
    """

    mean_xy: np.ndarray
    cov_xy: np.ndarray
    samples_xy: np.ndarray
    samples_polar: np.ndarray
    lin_mean: np.ndarray
    lin_cov: np.ndarray
    sample_mean: np.ndarray
    sample_cov: np.ndarray
    inside_share: float
    expected_share: float
    n_sigma: float


def cross_range_covariance(mean_xy, sigma_across, sigma_along):
    """Covariance of a position cloud stretched across a radar's line of sight.

    Parameters
    ----------
    mean_xy : array_like, shape (2,)
        The cloud's centre, m (the radar is at the origin); not at the radar.
    sigma_across : float
        Standard deviation across the line of sight, m (> 0).
    sigma_along : float
        Standard deviation along it, m (> 0).

    Returns
    -------
    ndarray, shape (2, 2)
        :math:`\\sigma_\\perp^2 w w^T + \\sigma_\\parallel^2 u u^T` with u the unit vector from
        the radar to ``mean_xy`` and w the unit vector across it.
    """
    mean_xy = as_vector(mean_xy, "mean_xy", 2)
    distance = float(np.hypot(*mean_xy))
    if distance < 1e-9:
        raise ValueError("mean_xy must not be at the radar's position (no line of sight)")
    across = as_scalar(sigma_across, "sigma_across")
    along = as_scalar(sigma_along, "sigma_along")
    u = mean_xy / distance
    w = np.array([-u[1], u[0]])
    return across**2 * np.outer(w, w) + along**2 * np.outer(u, u)


def radar_cloud(mean_xy, cov_xy, *, n_samples=2000, seed=0, n_sigma=3.0) -> RadarCloud:
    """Push samples of a position Gaussian through the radar's range and bearing.

    Uses the SymPy radar model (``symbolic.radar_observation`` and ``radar_jacobian``
    for a CV state at rest) and chapter 02's linear map for the linearised covariance.

    Parameters
    ----------
    mean_xy : array_like, shape (2,)
        Mean position, m; not at the radar.
    cov_xy : array_like, shape (2, 2)
        Position covariance, symmetric positive definite, m².
    n_samples : int
        Number of samples (>= 10).
    seed : int
        Seed of ``numpy.random.default_rng``.
    n_sigma : float
        Size of the ellipse for :attr:`RadarCloud.inside_share`.

    Returns
    -------
    RadarCloud
    """
    mean_xy = as_vector(mean_xy, "mean_xy", 2)
    if np.hypot(*mean_xy) < 1e-9:
        raise ValueError("mean_xy must not be at the radar's position (range 0 has no bearing)")
    cov_xy = as_covariance(cov_xy, "cov_xy", 2, positive_definite=True)
    if isinstance(n_samples, bool) or not isinstance(n_samples, (int, np.integer)) or n_samples < 10:
        raise ValueError(f"n_samples must be an integer >= 10, got {n_samples!r}")
    n_sigma = as_scalar(n_sigma, "n_sigma")
    rng = np.random.default_rng(as_seed(seed))
    samples = mean_xy + rng.standard_normal((int(n_samples), 2)) @ np.linalg.cholesky(cov_xy).T

    def polar(p):
        return symbolic.radar_observation(np.r_[p, 0.0, 0.0], "cv")[:2]

    lin_mean = polar(mean_xy)
    G = symbolic.radar_jacobian(np.r_[mean_xy, 0.0, 0.0], "cv")[:2, :2]
    _, lin_cov, _ = linear_map(mean_xy, cov_xy, G, np.zeros((2, 2)))
    # a sample exactly at the radar has no bearing; such a draw is (vanishingly) rare
    keep = np.hypot(samples[:, 0], samples[:, 1]) > 1e-9
    samples = samples[keep]
    out = np.array([polar(p) for p in samples])
    out[:, 1] = lin_mean[1] + wrap_angle(out[:, 1] - lin_mean[1])   # no jump at ±π
    d = out - lin_mean
    mahalanobis2 = np.einsum("ni,ij,nj->n", d, np.linalg.inv(lin_cov), d)
    return RadarCloud(mean_xy=mean_xy.copy(), cov_xy=np.array(cov_xy), samples_xy=samples, samples_polar=out,
                      lin_mean=lin_mean, lin_cov=lin_cov, sample_mean=out.mean(axis=0),
                      sample_cov=np.cov(out.T), inside_share=float(np.mean(mahalanobis2 <= n_sigma**2)),
                      expected_share=float(1.0 - np.exp(-0.5 * n_sigma**2)), n_sigma=n_sigma)


# --------------------------------------------------------------------------------------
# chapter 06: the cost one update minimises, and the IEKF's path on it
# --------------------------------------------------------------------------------------

def _cost_inputs(x_check, P_check, y, R, residual):
    x_check = as_vector(x_check, "x_check")
    n = x_check.shape[0]
    P_check = as_covariance(P_check, "P_check", n, positive_definite=True)
    y = as_vector(y, "y")
    R = as_covariance(R, "R", y.shape[0], positive_definite=True)
    if residual is None:
        residual = np.subtract
    elif not callable(residual):
        raise ValueError(f"residual must be a callable residual(y, y_pred) or None, got {type(residual).__name__}")
    return x_check, P_check, y, R, residual


def map_cost(x, x_check, P_check, y, g: Callable, R, residual=None) -> float:
    """The cost whose minimum is the posterior mode (MAP estimate) of one update.

    .. math::

        J(x) = \\tfrac12\\, r(y, g(x))^T R^{-1} r(y, g(x))
             + \\tfrac12\\, (x - \\check x)^T \\check P^{-1} (x - \\check x)

    Parameters
    ----------
    x : array_like, shape (n,)
        Where to evaluate it.
    x_check, P_check : array_like, shapes (n,), (n, n)
        The prior (P̌ positive definite).
    y : array_like, shape (m,)
        The measurement.
    g : callable
        ``g(x) -> (m,)``, the observation model.
    R : array_like, shape (m, m)
        Measurement-noise covariance, positive definite.
    residual : callable, optional
        ``residual(y, y_pred)``; default ``y − y_pred`` (wrap bearings with your own).

    Returns
    -------
    float
    """
    x_check, P_check, y, R, residual = _cost_inputs(x_check, P_check, y, R, residual)
    x = as_vector(x, "x", x_check.shape[0])
    if not callable(g):
        raise ValueError(f"g must be a callable g(x), got {type(g).__name__}")
    r = as_vector(residual(y, as_vector(g(x), "g(x)", y.shape[0])), "residual(y, g(x))", y.shape[0])
    d = x - x_check
    return float(0.5 * r @ np.linalg.solve(R, r) + 0.5 * d @ np.linalg.solve(P_check, d))


def gauss_newton_cost(x, x_op, x_check, P_check, y, g: Callable, G: Callable, R, residual=None) -> float:
    """The quadratic model of :func:`map_cost` that one (I)EKF step minimises.

    g is replaced by its tangent at the operating point :math:`x_{op}`:

    .. math::

        J_{op}(x) = \\tfrac12\\, e^T R^{-1} e + \\tfrac12\\, (x - \\check x)^T \\check P^{-1} (x - \\check x),
        \\qquad e = r(y, g(x_{op})) - G(x_{op})\\,(x - x_{op}).

    Its minimum is ``ekf.iekf_update``'s next iterate from :math:`x_{op}` (the EKF's
    :math:`\\hat x` when :math:`x_{op} = \\check x`). Arguments as :func:`map_cost`, plus
    ``x_op`` (n,) and the Jacobian ``G(x) -> (m, n)``.

    Returns
    -------
    float
    """
    x_check, P_check, y, R, residual = _cost_inputs(x_check, P_check, y, R, residual)
    n, m = x_check.shape[0], y.shape[0]
    x = as_vector(x, "x", n)
    x_op = as_vector(x_op, "x_op", n)
    if not callable(g) or not callable(G):
        raise ValueError("g and G must be callables g(x) and G(x)")
    r_op = as_vector(residual(y, as_vector(g(x_op), "g(x_op)", m)), "residual(y, g(x_op))", m)
    e = r_op - as_matrix(G(x_op), "G(x_op)", (m, n)) @ (x - x_op)
    d = x - x_check
    return float(0.5 * e @ np.linalg.solve(R, e) + 0.5 * d @ np.linalg.solve(P_check, d))


def cost_on_plane(cost: Callable, point, u, v, *, dims=(0, 1)):
    """Evaluate a cost over a grid in the plane of two state components through ``point``.

    Parameters
    ----------
    cost : callable
        ``cost(x) -> float`` of a full state x (n,).
    point : array_like, shape (n,)
        The other components are held at their values here.
    u, v : array_like, shapes (nu,), (nv,)
        Values of components ``dims[0]`` and ``dims[1]``.
    dims : (int, int)
        Which components vary.

    Returns
    -------
    U, V, J : ndarray, shape (nv, nu)
        ``numpy.meshgrid(u, v)`` and the cost at each node.
    """
    if not callable(cost):
        raise ValueError(f"cost must be a callable cost(x), got {type(cost).__name__}")
    point = as_vector(point, "point")
    u, v = as_vector(u, "u"), as_vector(v, "v")
    i, j = (int(d) for d in dims)
    if i == j or not (0 <= i < point.shape[0] and 0 <= j < point.shape[0]):
        raise ValueError(f"dims must be two different components of the {point.shape[0]}-state, got {dims}")
    U, V = np.meshgrid(u, v)
    J = np.empty(U.shape)
    x = point.copy()
    for idx in np.ndindex(U.shape):
        x[i], x[j] = U[idx], V[idx]
        J[idx] = cost(x)
    return U, V, J


def iekf_iterates(x_check, P_check, y, g: Callable, G: Callable, R, residual=None, *, max_iter=10, tol=1e-9):
    """The points the iterated EKF visits: x̌, then the iterate after each linearisation.

    Iterate i is ``ekf.iekf_update(..., max_iter=i).x_hat``; the list stops at the first
    iterate the update reports as converged (or at ``max_iter``).

    Returns
    -------
    ndarray, shape (k + 1, n)
        Row 0 is x̌, row 1 the EKF's x̂, the last row the IEKF's x̂.
    """
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    path = [as_vector(x_check, "x_check")]
    for i in range(1, int(max_iter) + 1):
        upd = iekf_update(x_check, P_check, y, g, G, R, residual=residual, max_iter=i, tol=tol)
        path.append(upd.x_hat)
        if upd.converged:
            break
    return np.array(path)


# --------------------------------------------------------------------------------------
# chapter 01: a Gaussian prior cut off by the edges of a grid
# --------------------------------------------------------------------------------------

def truncated_normal_moments(mu, sigma, low, high) -> tuple[float, float]:
    """Mean and standard deviation of N(mu, sigma²) restricted to [low, high].

    The closed form of the truncated normal: with a = (low − mu)/sigma,
    b = (high − mu)/sigma, φ the standard normal density and Z = Φ(b) − Φ(a),

    mean = mu + sigma (φ(a) − φ(b)) / Z,
    var  = sigma² [1 + (a φ(a) − b φ(b)) / Z − ((φ(a) − φ(b)) / Z)²].

    Parameters
    ----------
    mu, sigma : float
        Mean and standard deviation (> 0) of the untruncated Gaussian.
    low, high : float
        The interval kept, low < high.

    Returns
    -------
    mean, std : float
        The moments of the truncated density.
    """
    from math import erf, exp, pi, sqrt

    mu, low, high = (float(as_vector([v], name, 1)[0]) for v, name in ((mu, "mu"), (low, "low"), (high, "high")))
    sigma = as_scalar(sigma, "sigma")
    if not low < high:
        raise ValueError(f"low must be below high, got [{low}, {high}]")
    a, b = (low - mu) / sigma, (high - mu) / sigma
    phi = lambda t: exp(-0.5 * t * t) / sqrt(2 * pi)  # noqa: E731
    Phi = lambda t: 0.5 * (1 + erf(t / sqrt(2)))  # noqa: E731
    Z = Phi(b) - Phi(a)
    if not Z > 0:
        raise ValueError(f"[{low}, {high}] holds no probability of N({mu}, {sigma}²) in float64")
    shift = (phi(a) - phi(b)) / Z
    var = sigma**2 * (1 + (a * phi(a) - b * phi(b)) / Z - shift**2)
    return float(mu + sigma * shift), float(np.sqrt(var))


# --------------------------------------------------------------------------------------
# chapter 02: does an observation always help?
# --------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class InformationTrial:
    """Errors before and after one linear-Gaussian update, over runs and seeds.

    Every run draws its own truth x from the prior N(mu, P_check) and its own observation
    y = G x + bias + n with n ~ N(0, R_true); the estimator conditions the prior on y with
    its model (G, R), which knows neither the truth nor the bias.

    Attributes
    ----------
    seeds : ndarray, shape (S,)
        The seeds, one batch of runs each.
    prior_sq_error, posterior_sq_error : ndarray, shape (S, n_runs)
        Squared error ‖mu − x‖² of the prior mean and ‖x̂ − x‖² of the posterior mean.
    prior_trace, posterior_trace : float
        trace P̌ and trace P̂: the mean squared errors the model predicts.
    covariance_drop : ndarray, shape (n,)
        Eigenvalues of P̌ − P̂ (never negative for a linear-Gaussian update).
    """

    seeds: np.ndarray
    prior_sq_error: np.ndarray
    posterior_sq_error: np.ndarray
    prior_trace: float
    posterior_trace: float
    covariance_drop: np.ndarray

    @property
    def mse_ratio(self) -> np.ndarray:
        """Per seed: mean posterior squared error over mean prior squared error, shape (S,)."""
        return self.posterior_sq_error.mean(axis=1) / self.prior_sq_error.mean(axis=1)

    @property
    def share_worse(self) -> np.ndarray:
        """Per seed: the share of runs whose error grew with the observation, shape (S,)."""
        return (self.posterior_sq_error > self.prior_sq_error).mean(axis=1)


def information_trial(mu, P_check, G, R, *, seeds, n_runs=500, bias=None, R_true=None) -> InformationTrial:
    """Condition a Gaussian prior on one linear observation, many times, and score it.

    Parameters
    ----------
    mu : array_like, shape (n,)
        Prior mean (the truth of each run is drawn from N(mu, P_check)).
    P_check : array_like, shape (n, n)
        Prior covariance.
    G : array_like, shape (m, n)
        Observation matrix.
    R : array_like, shape (m, m)
        Observation noise covariance the estimator assumes.
    seeds : sequence of int
        One batch of ``n_runs`` runs per seed.
    n_runs : int
        Runs per seed.
    bias : array_like, shape (m,), optional
        A constant sensor offset the estimator does not model (default none).
    R_true : array_like, shape (m, m), optional
        The noise covariance the observations are drawn with (default ``R``).

    Returns
    -------
    InformationTrial
    """
    mu = as_vector(mu, "mu")
    n = mu.shape[0]
    P_check = as_covariance(P_check, "P_check", n)
    G = as_matrix(G, "G")
    if G.shape[1] != n:
        raise ValueError(f"G must have {n} columns, got shape {G.shape}")
    m = G.shape[0]
    _check_rows_of_G(R, "R", G)
    R = as_covariance(R, "R", m)
    R_true = R if R_true is None else as_covariance(R_true, "R_true", m)
    bias = np.zeros(m) if bias is None else as_vector(bias, "bias", m)
    if isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer)) or n_runs < 1:
        raise ValueError(f"n_runs must be an integer >= 1, got {n_runs!r}")
    seeds = _seed_list(seeds)

    # the update is the same for every run: x̂ = mu + K (y − G mu), P̂ = P̌ − K G P̌
    K = kf_gain(P_check, G, innovation_covariance(P_check, G, R))
    P_hat = P_check - K @ G @ P_check
    L_prior, L_noise = np.linalg.cholesky(P_check), np.linalg.cholesky(R_true)
    prior_sq, post_sq = [], []
    for seed in seeds:
        rng = np.random.default_rng(int(seed))
        x_true = mu + rng.standard_normal((n_runs, n)) @ L_prior.T
        y = x_true @ G.T + bias + rng.standard_normal((n_runs, m)) @ L_noise.T
        x_hat = mu + (y - G @ mu) @ K.T
        prior_sq.append(np.sum((mu - x_true) ** 2, axis=1))
        post_sq.append(np.sum((x_hat - x_true) ** 2, axis=1))
    return InformationTrial(seeds=seeds, prior_sq_error=np.array(prior_sq), posterior_sq_error=np.array(post_sq),
                            prior_trace=float(np.trace(P_check)), posterior_trace=float(np.trace(P_hat)),
                            covariance_drop=np.linalg.eigvalsh(0.5 * ((P_check - P_hat) + (P_check - P_hat).T)))


# --------------------------------------------------------------------------------------
# chapter 02: conditioning two scalars before the block algebra, and folding SymPy's output
# --------------------------------------------------------------------------------------

def correlated_pair_covariance(sigma_x, sigma_y, rho) -> np.ndarray:
    """The covariance matrix of two scalars x and y with given spreads and correlation.

    Parameters
    ----------
    sigma_x, sigma_y : float
        Standard deviations σ_x of x and σ_y of y (> 0).
    rho : float
        Correlation coefficient ρ of x and y, strictly between −1 and 1 (at ±1 the pair lies
        on a line and has no density).

    Returns
    -------
    ndarray, shape (2, 2)
        ``[[σ_x², ρ σ_x σ_y], [ρ σ_x σ_y, σ_y²]]``, the order being (x, y).

    Raises
    ------
    ValueError
        Naming the argument: a standard deviation that is not a positive number, a ``rho``
        that is not a finite number in (−1, 1).
    """
    sx = as_scalar(sigma_x, "sigma_x")
    sy = as_scalar(sigma_y, "sigma_y")
    r = float(as_vector([rho], "rho", 1)[0])
    if not -1.0 < r < 1.0:
        raise ValueError(f"rho must lie strictly between -1 and 1, got {rho!r}")
    cross = r * sx * sy
    return np.array([[sx * sx, cross], [cross, sy * sy]])


@functools.lru_cache(maxsize=None)
def scalar_conditioning():
    """SymPy's check of p(x | y) for two jointly Gaussian scalars, step by step.

    The route is the one lecture 02 writes out before any block matrix: split
    :math:`x - \\mu_x = a (y - \\mu_y) + w`, choose a so that w and y are uncorrelated
    (hence independent, the pair being jointly Gaussian), and read the conditional off:

    .. math::

        a = \\rho\\,\\sigma_x / \\sigma_y, \\qquad
        \\mu_{x|y} = \\mu_x + a (y - \\mu_y), \\qquad
        \\sigma^2_{x|y} = \\operatorname{Var} w = \\sigma_x^2 (1 - \\rho^2).

    Two further identities close the loop: the general block formula of the lecture's
    section 4 with 1 × 1 blocks gives the same mean and variance, and the joint exponent
    and determinant split into the conditional's times the marginal's (which proves the
    factorisation without the independence argument).

    Returns
    -------
    kalman_course.symbolic.equations.Derivation
        Name ``"scalar_conditioning"``; ``verify()`` proves every identity. Symbols for
        ``evaluate``: ``mu_x``, ``mu_y``, ``sigma_x``, ``sigma_y``, ``rho``, ``y``; results
        ``"slope"`` (a), ``"mean"`` (μ_{x|y}) and ``"var"`` (σ²_{x|y}), each a scalar.
    """
    x, y, mu_x, mu_y, a, w = sp.symbols("x y mu_x mu_y a w", real=True)
    sigma_x, sigma_y = sp.symbols("sigma_x sigma_y", positive=True)
    rho = sp.Symbol("rho", real=True)
    cross = rho * sigma_x * sigma_y
    Sigma = sp.Matrix([[sigma_x**2, cross], [cross, sigma_y**2]])
    # w = c · [x − μ_x, y − μ_y]: its covariances follow from Σ by bilinearity
    c = sp.Matrix([[1, -a]])
    picks_y = sp.Matrix([0, 1])
    cov_wy = (c * Sigma * picks_y)[0, 0]
    c_at_slope = c.subs(a, rho * sigma_x / sigma_y)
    solved = sp.solve(sp.Eq(cov_wy, 0), a)
    if len(solved) != 1:
        raise RuntimeError(f"Cov(w, y) = 0 should fix a uniquely, SymPy found {solved}")
    slope = rho * sigma_x / sigma_y
    mean = mu_x + slope * (y - mu_y)
    var = sigma_x**2 * (1 - rho**2)

    # section 4's general result with every block 1 × 1
    general = symbolic.gaussian_conditioning()
    S = general.symbols
    dims = {S["n"]: 1, S["m"]: 1}
    one = {S[k].subs(dims): sp.Matrix([[v]]) for k, v in
           (("mu_x", mu_x), ("mu_y", mu_y), ("Sigma_xx", sigma_x**2), ("Sigma_xy", cross),
            ("Sigma_yy", sigma_y**2), ("y", y))}
    block_mean = general.results["mean"].subs(dims).xreplace(one)
    block_cov = general.results["cov"].subs(dims).xreplace(one)

    e = sp.Matrix([x - mu_x, y - mu_y])
    equations = (
        Equation("split", w, (x - mu_x) - a * (y - mu_y),
                 "the part of $x - \\mu_x$ that a multiple of $y - \\mu_y$ does not explain", "definition"),
        Equation("cov_wy", sp.MatMul(c, Sigma, picks_y, evaluate=False), sp.Matrix([[cross - a * sigma_y**2]]),
                 "$\\operatorname{Cov}(w, y) = \\rho\\sigma_x\\sigma_y - a\\sigma_y^2$, from $\\Sigma$ by bilinearity"),
        Equation("slope", solved[0], slope,
                 "$\\operatorname{Cov}(w, y) = 0$ exactly when $a = \\rho\\sigma_x/\\sigma_y$"),
        Equation("var_w_any_a", sp.MatMul(c, Sigma, c.T, evaluate=False),
                 sp.Matrix([[sigma_x**2 - 2 * a * rho * sigma_x * sigma_y + a**2 * sigma_y**2]]),
                 "$\\operatorname{Var} w = \\sigma_x^2 - 2a\\rho\\sigma_x\\sigma_y + a^2\\sigma_y^2$ for any $a$"),
        Equation("var_w", sp.MatMul(c_at_slope, Sigma, c_at_slope.T, evaluate=False), sp.Matrix([[var]]),
                 "with that $a$, $\\operatorname{Var} w = \\sigma_x^2(1 - \\rho^2)$"),
        Equation("mean_from_blocks", block_mean, sp.Matrix([[mean]]),
                 "the block formula's mean with $1 \\times 1$ blocks is the same"),
        Equation("var_from_blocks", block_cov, sp.Matrix([[var]]),
                 "the block formula's covariance with $1 \\times 1$ blocks is the same"),
        Equation("exponent_split", (e.T * Sigma.inv() * e)[0, 0],
                 (x - mean) ** 2 / var + (y - mu_y) ** 2 / sigma_y**2,
                 "the joint exponent (SymPy's own inverse of $\\Sigma$) is the conditional's plus the marginal's"),
        Equation("determinant_split", Sigma.det(), var * sigma_y**2,
                 "$\\det\\Sigma = \\sigma^2_{x|y}\\,\\sigma_y^2$, so the normalising constants split too"),
    )
    return Derivation(
        name="scalar_conditioning",
        title="Conditioning two jointly Gaussian scalars",
        model=("$x \\sim \\mathcal N(\\mu_x, \\sigma_x^2)$ and $y \\sim \\mathcal N(\\mu_y, \\sigma_y^2)$ jointly "
               "Gaussian with correlation $\\rho$, $|\\rho| < 1$."),
        equations=equations,
        symbols=dict(mu_x=mu_x, mu_y=mu_y, sigma_x=sigma_x, sigma_y=sigma_y, rho=rho, y=y),
        results=dict(slope=slope, mean=mean, var=var),
    )


@dataclass(frozen=True, eq=False)
class WindowSlice:
    """The samples of a joint (x, y) whose y falls within a narrow window around y_obs.

    A Monte Carlo stand-in for p(x | y = y_obs): only approximately, because inside the
    window y still varies a little. With a conditional mean linear in y (slope a), that
    spread shifts the window's mean of x by a (ȳ − y_obs) and widens its variance by
    a² Var(y | window); :meth:`mean_tolerance` and :meth:`var_tolerance` allow for both.

    Attributes
    ----------
    y_obs, half_width : float
        The window is ``|y − y_obs| < half_width``.
    x : ndarray, shape (K,)
        The x of the K samples inside it.
    y_offset : float
        Mean of their y minus y_obs.
    y_spread : float
        Mean of their (y − y_obs)², at most half_width².
    """

    y_obs: float
    half_width: float
    x: np.ndarray
    y_offset: float
    y_spread: float

    @property
    def n(self) -> int:
        """Number of samples in the window, K."""
        return int(self.x.shape[0])

    @property
    def x_mean(self) -> float:
        """Sample mean of x in the window."""
        return float(np.mean(self.x))

    @property
    def x_var(self) -> float:
        """Sample variance of x in the window (divided by K − 1)."""
        return float(np.var(self.x, ddof=1))

    def mean_tolerance(self, slope, n_se=4.0) -> float:
        """How far the window's mean may sit from μ_{x|y} if the formula is right.

        ``n_se`` standard errors of a mean, √(s²/K), plus |a| |ȳ − y_obs| for the window's
        own offset; ``slope`` is a, the slope of E[x | y] in y.
        """
        a = float(as_vector([slope], "slope", 1)[0])
        k = as_scalar(n_se, "n_se")
        return k * float(np.sqrt(self.x_var / self.n)) + abs(a) * abs(self.y_offset)

    def var_tolerance(self, slope, n_se=4.0) -> float:
        """How far the window's variance may sit from σ²_{x|y} if the formula is right.

        ``n_se`` standard errors of a Gaussian sample variance, s² √(2 / (K − 1)), plus
        a² times the window's spread in y (the widening it causes).
        """
        a = float(as_vector([slope], "slope", 1)[0])
        k = as_scalar(n_se, "n_se")
        return k * self.x_var * float(np.sqrt(2.0 / (self.n - 1))) + a * a * self.y_spread


def window_slice(samples, y_obs, half_width) -> WindowSlice:
    """Keep the samples of (x, y) whose y lies within ``half_width`` of ``y_obs``.

    Parameters
    ----------
    samples : array_like, shape (N, 2)
        Draws of the joint, one (x, y) per row.
    y_obs : float
        The observed value of y.
    half_width : float
        Half the window's width (> 0), in the units of y.

    Returns
    -------
    WindowSlice

    Raises
    ------
    ValueError
        Naming the argument: ``samples`` not a finite (N, 2) array, a non-finite ``y_obs``,
        a ``half_width`` that is not positive, or a window holding fewer than two samples.
    """
    pts = as_real_array(samples, "samples")
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"samples must have shape (N, 2), one (x, y) per row, got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("samples must be finite")
    y0 = float(as_vector([y_obs], "y_obs", 1)[0])
    h = as_scalar(half_width, "half_width")
    inside = np.abs(pts[:, 1] - y0) < h
    if inside.sum() < 2:
        raise ValueError(f"half_width={h:g} keeps {int(inside.sum())} samples around y_obs={y0:g}; "
                         "widen it or draw more samples")
    dy = pts[inside, 1] - y0
    return WindowSlice(y_obs=y0, half_width=h, x=pts[inside, 0].copy(), y_offset=float(np.mean(dy)),
                       y_spread=float(np.mean(dy * dy)))


def ellipse_highest_point(mean, cov, n_sigma, n_points=100_001) -> np.ndarray:
    """The point of a 2-D Gaussian's ``n_sigma`` ellipse with the largest second coordinate.

    Found numerically: ``n_points`` points μ + k L [cos t, sin t] of the boundary (L the
    Cholesky factor of Σ), then the highest one, so the answer does not lean on any formula
    for the conditional.

    Parameters
    ----------
    mean : array_like, shape (2,)
        Centre μ.
    cov : array_like, shape (2, 2)
        Covariance Σ, symmetric positive definite.
    n_sigma : float
        Mahalanobis radius k (> 0).
    n_points : int
        Points on the boundary (>= 8); the answer is good to about 2π k σ / n_points.

    Returns
    -------
    ndarray, shape (2,)
    """
    mean = as_vector(mean, "mean", 2)
    cov = as_covariance(cov, "cov", 2, positive_definite=True)
    k = as_scalar(n_sigma, "n_sigma")
    if isinstance(n_points, bool) or not isinstance(n_points, (int, np.integer)) or n_points < 8:
        raise ValueError(f"n_points must be an integer >= 8, got {n_points!r}")
    t = np.linspace(0.0, 2 * np.pi, int(n_points), endpoint=False)
    boundary = mean + k * np.column_stack([np.cos(t), np.sin(t)]) @ np.linalg.cholesky(cov).T
    return boundary[np.argmax(boundary[:, 1])]


@dataclass(frozen=True, eq=False)
class ChainCheck:
    """Which SymPy identities prove each line of a derivation written out by hand.

    Attributes
    ----------
    name : str
        The derivation's name.
    rows : tuple of (str, tuple of str, bool)
        One per written step: its text, the labels of the identities behind it, and
        whether SymPy proves all of them.
    unnamed : tuple of str
        Identities the derivation proves that no written step names.
    """

    name: str
    rows: tuple
    unnamed: tuple

    @property
    def all_hold(self) -> bool:
        """True if every written step is proved."""
        return all(ok for _, _, ok in self.rows)

    def to_text(self) -> str:
        """One line per step: 'proved' or 'FAILS', the step, the SymPy labels."""
        width = max(len(step) for step, _, _ in self.rows)
        lines = [f"{'proved' if ok else 'FAILS ':6s}  {step:{width}s}  <- {', '.join(labels)}"
                 for step, labels, ok in self.rows]
        if self.unnamed:
            lines.append(f"not named by any step: {', '.join(self.unnamed)}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.to_text()


def check_chain(derivation, steps) -> ChainCheck:
    """Prove the identities behind each line of a hand-written chain of steps.

    Parameters
    ----------
    derivation : kalman_course.symbolic.equations.Derivation
        The SymPy derivation the chain summarises.
    steps : mapping of str to sequence of str
        For each written step, in reading order, the labels of the identities or checks
        of ``derivation`` that prove it (definitions prove nothing and are refused).

    Returns
    -------
    ChainCheck

    Raises
    ------
    ValueError
        Naming ``steps``: empty, a step with no label, a label the derivation lacks, or a
        label that is a definition.
    """
    if not isinstance(derivation, Derivation):
        raise ValueError(f"derivation must be a Derivation, got {type(derivation).__name__}")
    if not hasattr(steps, "items") or not steps:
        raise ValueError("steps must be a non-empty mapping from a written step to SymPy labels")
    rows, named = [], set()
    for step, labels in steps.items():
        labels = (labels,) if isinstance(labels, str) else tuple(labels)
        if not labels:
            raise ValueError(f"steps: {step!r} names no identity")
        for label in labels:
            if label not in derivation.labels:
                raise ValueError(f"steps: {step!r} names {label!r}, which {derivation.name!r} lacks; "
                                 f"labels: {derivation.labels}")
            if not derivation[label].checked:
                raise ValueError(f"steps: {step!r} names {label!r}, a definition, which proves nothing")
        named.update(labels)
        rows.append((str(step), labels, all(derivation[label].holds() for label in labels)))
    unnamed = tuple(e.label for e in derivation.equations if e.checked and e.label not in named)
    return ChainCheck(name=derivation.name, rows=tuple(rows), unnamed=unnamed)


class Folded:
    """A derivation shown folded: a one-line summary that opens to SymPy's full Markdown.

    Displayed in a notebook as an HTML ``<details>`` element, closed until clicked.

    Parameters
    ----------
    derivation : kalman_course.symbolic.equations.Derivation
        What to fold.
    summary : str
        The text shown while it is closed.
    """

    def __init__(self, derivation, summary: str):
        if not isinstance(derivation, Derivation):
            raise ValueError(f"derivation must be a Derivation, got {type(derivation).__name__}")
        if not isinstance(summary, str) or not summary.strip():
            raise ValueError("summary must be a non-empty string")
        self.derivation = derivation
        self.summary = summary.strip()

    def _repr_markdown_(self) -> str:
        # blank lines around the body: Markdown inside an HTML block is parsed only after one
        return (f"<details>\n<summary>{html.escape(self.summary, quote=False)}</summary>\n\n"
                f"{self.derivation.to_markdown()}\n</details>\n")

    def __repr__(self) -> str:
        return f"{self.summary} (folded; {self.derivation!r})"
