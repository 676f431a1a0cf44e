"""The numbers behind the course's intuition figures (chapters 01, 02, 03, 05 and 06).

Each function here computes what one picture shows, with the filters of the layers below
(no filter equation is written again here):

- chapter 01: :func:`truncated_normal_moments`, the moments of a Gaussian prior cut off
  by the ends of a grid;
- chapter 02: :func:`information_trial`, one linear-Gaussian update repeated over runs
  and seeds, scored against truths the estimator does not see (:class:`InformationTrial`);
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

from dataclasses import dataclass
from typing import Callable

import numpy as np

from kalman_course import symbolic
from kalman_course.core.angles import wrap_angle
from kalman_course.core.gaussians import linear_map
from kalman_course.core.validation import (as_covariance, as_matrix, as_real_array, as_scalar, as_seed,
                                           as_vector)
from kalman_course.filters.ekf import iekf_update
from kalman_course.filters.kf import innovation_covariance, kf_gain, kf_predict, kf_update, run_kf

__all__ = ["KF1DTable", "kf_1d_table", "scalar_gain", "SteadyState", "steady_state", "RadarCloud",
           "cross_range_covariance", "radar_cloud", "map_cost", "gauss_newton_cost", "cost_on_plane", "iekf_iterates",
           "truncated_normal_moments", "InformationTrial", "information_trial"]


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
    G = as_matrix(G, "G", (None, n))
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
    R = as_covariance(R, "R", m)
    R_true = R if R_true is None else as_covariance(R_true, "R_true", m)
    bias = np.zeros(m) if bias is None else as_vector(bias, "bias", m)
    if isinstance(n_runs, bool) or not isinstance(n_runs, (int, np.integer)) or n_runs < 1:
        raise ValueError(f"n_runs must be an integer >= 1, got {n_runs!r}")
    seeds = np.array([as_seed(s) for s in seeds], dtype=int)
    if seeds.size == 0:
        raise ValueError("seeds must name at least one seed")

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
