"""The extended Kalman filter and the iterated EKF (chapters 05 and 06).

Lecture notation: prior :math:`\\check x, \\check P`, posterior :math:`\\hat x, \\hat P`;
motion model :math:`x_k = f(x_{k-1}, w_k)` with Jacobians
:math:`F = \\partial f / \\partial x` and :math:`B = \\partial f / \\partial w` at
:math:`(\\hat x_{k-1}, 0)`; observation :math:`y_k = g(x_k) + C n_k` with Jacobian
:math:`G = \\partial g / \\partial x` at the linearisation point.

.. math::

    \\check x_k &= f(\\hat x_{k-1}, 0), \\qquad
    \\check P_k = F \\hat P_{k-1} F^T + B Q B^T \\\\
    K_k &= \\check P_k G^T (G \\check P_k G^T + C R C^T)^{-1} \\\\
    \\hat x_k &= \\check x_k + K_k \\, r(y_k, g(\\check x_k)), \\qquad
    \\hat P_k = (I - K_k G) \\check P_k

where :math:`r(y, \\check y)` is the residual, :math:`y - \\check y` unless the
measurement holds angles (then :func:`radar_residual` wraps the bearing).

The iterated EKF (:func:`iekf_update`) relinearises g at its newest iterate
:math:`x_{op}`:

.. math::

    x_{i+1} = \\check x + K_i \\big( r(y, g(x_i)) - G_i (\\check x - x_i) \\big),

which is a Gauss–Newton step on
:math:`\\tfrac12 \\|y - g(x)\\|^2_{R^{-1}} + \\tfrac12 \\|x - \\check x\\|^2_{\\check P^{-1}}`.
Only the mean iterates; the covariance is formed once, at the end.

The gain and both covariance updates are the shared kernels of
:mod:`kalman_course.core.linalg`. Every public function validates its arguments, and
the values its callables return, at its boundary: a ``ValueError`` names the argument
(``G(x_check)`` for what a callable ``G`` returned) and what was expected.

The chapters' experiments built on these steps live in
:mod:`kalman_course.chapters.lidar_radar` (chapter 05) and
:mod:`kalman_course.chapters.beacons` (chapter 06).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np
from numpy import dot

from kalman_course.core.angles import wrap_angle
from kalman_course.core.linalg import (gain, innovation_covariance, joseph_update, predict_covariance,
                                        short_update)
from kalman_course.core.validation import (as_covariance, as_flag, as_matrix, as_observation_noise,
                                           as_process_noise, as_vector)
from kalman_course.filters.kf import KFUpdate

__all__ = [
    "ekf_predict", "ekf_update", "iekf_update", "IEKFUpdate", "KFUpdate", "radar_residual",
    "lidar_observation", "lidar_jacobian", "LIDAR_G",
]


class IEKFUpdate(NamedTuple):
    """The result of an iterated EKF update.

    Attributes
    ----------
    x_hat : ndarray, shape (n,)
        Posterior mean, the last iterate.
    P_hat : ndarray, shape (n, n)
        Posterior covariance :math:`(I - K G) \\check P` with K and G of the last
        linearisation, symmetric.
    innovation : ndarray, shape (m,)
        :math:`r(y, g(x_{op}))` at the last linearisation point.
    S : ndarray, shape (m, m)
        Innovation covariance at the last linearisation point.
    K : ndarray, shape (n, m)
        Gain at the last linearisation point.
    iterations : int
        Number of linearisations used (1 = a plain EKF update).
    converged : bool
        True if the last step was below the tolerance.
    """

    x_hat: np.ndarray
    P_hat: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    K: np.ndarray
    iterations: int
    converged: bool


# ---------------------------------------------------------------------------------------
# residuals and the lidar observation
# ---------------------------------------------------------------------------------------

def radar_residual(y, y_pred) -> np.ndarray:
    """Radar residual ``y − y_pred`` with the bearing difference wrapped to (−π, π].

    Without the wrap a target near the negative x axis, where the bearing jumps from π
    to −π, produces a residual of almost 2π and throws the estimate away.

    Parameters
    ----------
    y : array_like, shape (3,)
        Measured [ρ (m), φ (rad), ρ̇ (m/s)].
    y_pred : array_like, shape (3,)
        Predicted measurement g(x) in the same order.

    Returns
    -------
    ndarray, shape (3,)
        [Δρ, wrapped Δφ, Δρ̇].
    """
    e = as_vector(y, "y", 3) - as_vector(y_pred, "y_pred", 3)
    e[1] = wrap_angle(e[1])
    return e


#: Lidar observation Jacobian G (2, 5) for the CTRV state: it sees p_x and p_y.
#: Read-only, so that a caller cannot change the model by writing into it.
LIDAR_G = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0]])
LIDAR_G.setflags(write=False)


def lidar_observation(x) -> np.ndarray:
    """Lidar measurement function g(x) = [p_x, p_y] (2,) of a CTRV state x (5,)."""
    return as_vector(x, "x", 5)[:2].copy()


def lidar_jacobian(x) -> np.ndarray:
    """Lidar Jacobian G (2, 5) at a CTRV state x (5,): constant, :data:`LIDAR_G`."""
    as_vector(x, "x", 5)
    return LIDAR_G


# ---------------------------------------------------------------------------------------
# boundary checks of what the callables return
# ---------------------------------------------------------------------------------------

def _require_callable(fn, name: str, what: str) -> None:
    if not callable(fn):
        raise ValueError(f"{name} must be a callable {what}, got {type(fn).__name__}")


def _jacobian(value, x, name: str, at: str, shape) -> np.ndarray:
    """A Jacobian given as a callable of the state (evaluated at ``x``) or as its value.

    The error names the argument (``G``) or the call (``G(x_check)``) and the shape expected.
    """
    if callable(value):
        return as_matrix(value(x), f"{name}({at})", shape)
    return as_matrix(value, name, shape)


# ---------------------------------------------------------------------------------------
# the filter steps
# ---------------------------------------------------------------------------------------

def ekf_predict(x_hat, P_hat, f: Callable, F, Q, B=None):
    """EKF prediction through a nonlinear motion model.

    .. math::

        \\check x = f(\\hat x), \\qquad \\check P = F \\hat P F^T + B Q B^T

    Parameters
    ----------
    x_hat : array_like, shape (n,)
        Posterior mean at the previous step.
    P_hat : array_like, shape (n, n)
        Posterior covariance at the previous step, symmetric.
    f : callable
        ``f(x) -> (n,)``: the motion model with zero noise (time step and inputs bound in).
    F : callable or array_like, shape (n, n)
        Motion Jacobian ``F(x)`` (evaluated at ``x_hat``) or its value.
    Q : array_like, shape (q, q) or (n, n)
        Process-noise covariance; (n, n) when ``B`` is None.
    B : callable or array_like, shape (n, q), optional
        Process-noise Jacobian ``B(x)`` or its value; None means the identity.

    Returns
    -------
    x_check : ndarray, shape (n,)
    P_check : ndarray, shape (n, n), symmetric

    Raises
    ------
    ValueError
        Naming the argument: ``f`` not callable, a shape that does not match (also of
        what ``f``, ``F`` or ``B`` returned, named ``f(x_hat)``, ``F(x_hat)``,
        ``B(x_hat)``), a non-finite value, a covariance that is not symmetric or not
        positive semi-definite.
    """
    _require_callable(f, "f", "f(x) returning the predicted state")
    x_hat = as_vector(x_hat, "x_hat")
    n = x_hat.shape[0]
    P_hat = as_covariance(P_hat, "P_hat", n, psd=True)
    Fm = _jacobian(F, x_hat, "F", "x_hat", (n, n))
    Bm = None if B is None else _jacobian(B, x_hat, "B", "x_hat", (n, None))
    BQBt = as_process_noise(Q, Bm, n)
    x_check = as_vector(f(x_hat), "f(x_hat)", n)
    return x_check, predict_covariance(P_hat, Fm, BQBt)


def _update_inputs(x_check, P_check, y, g, R, C, residual):
    """Validate what :func:`ekf_update` and :func:`iekf_update` share."""
    _require_callable(g, "g", "g(x) returning the predicted measurement")
    x_check = as_vector(x_check, "x_check")
    n = x_check.shape[0]
    P_check = as_covariance(P_check, "P_check", n, psd=True)
    y = as_vector(y, "y")
    m = y.shape[0]
    CRCt = as_observation_noise(R, C, m)
    if residual is None:
        residual = np.subtract
    else:
        _require_callable(residual, "residual", "residual(y, y_pred) or None")
    return x_check, P_check, y, n, m, CRCt, residual


def _innovation(residual, y, g, x, at: str, m: int) -> np.ndarray:
    """r(y, g(x)) with both the prediction and the residual checked as (m,) vectors."""
    y_pred = as_vector(g(x), f"g({at})", m)
    return as_vector(residual(y, y_pred), f"residual(y, g({at}))", m)


def ekf_update(x_check, P_check, y, g: Callable, G, R, C=None, residual=None, joseph=True):
    """EKF update: linearise g at the prior mean and apply the Kalman update.

    Parameters
    ----------
    x_check : array_like, shape (n,)
        Prior mean.
    P_check : array_like, shape (n, n)
        Prior covariance, symmetric.
    y : array_like, shape (m,)
        The measurement.
    g : callable
        ``g(x) -> (m,)``, the observation model.
    G : callable or array_like, shape (m, n)
        Observation Jacobian ``G(x)`` (evaluated at ``x_check``) or its value.
    R : array_like, shape (m, m) or (r, r)
        Observation-noise covariance, symmetric positive definite.
    C : array_like, shape (m, r), optional
        Observation-noise Jacobian; None means the identity.
    residual : callable, optional
        ``residual(y, y_pred) -> (m,)``; default ``y − y_pred``. Use
        :func:`radar_residual` for measurements with a bearing.
    joseph : bool, default True
        Joseph form of the covariance update (accurate where an update shrinks a variance by
        many orders of magnitude: :func:`kalman_course.filters.kf.kf_update`); False: the
        short form (I − K G) P̌.

    Returns
    -------
    KFUpdate
        ``(x_hat, P_hat, innovation, S, K)``.

    Raises
    ------
    ValueError
        Naming the argument, or the call whose result is wrong (``g(x_check)``,
        ``G(x_check)``, ``residual(y, g(x_check))``): a shape that does not match, a
        non-finite value, a P̌ that is not symmetric or not positive semi-definite, an R
        that is not positive definite.
    """
    x_check, P_check, y, n, m, CRCt, residual = _update_inputs(x_check, P_check, y, g, R, C, residual)
    Gm = _jacobian(G, x_check, "G", "x_check", (m, n))
    innovation = _innovation(residual, y, g, x_check, "x_check", m)
    GP = dot(Gm, P_check)                                  # G P̌
    S = innovation_covariance(GP, Gm, CRCt)                # S = G P̌ Gᵀ + C R Cᵀ
    K = gain(GP, S)                                        # K = P̌ Gᵀ S⁻¹
    x_hat = x_check + dot(K, innovation)                   # x̂ = x̌ + K r(y, g(x̌))
    P_hat = joseph_update(P_check, K, Gm, CRCt) if as_flag(joseph, "joseph") else short_update(P_check, K, GP)
    return KFUpdate(x_hat, P_hat, innovation, S, K)


def iekf_update(x_check, P_check, y, g: Callable, G: Callable, R, C=None, residual=None,
                tol: float = 1e-9, max_iter: int = 20, joseph=True) -> IEKFUpdate:
    """Iterated EKF update (Gauss–Newton on the measurement).

    Starting from :math:`x_0 = \\check x`, each iteration linearises g at the newest
    iterate :math:`x_i` and sets

    .. math::

        x_{i+1} = \\check x + K_i \\big(r(y, g(x_i)) - G_i (\\check x - x_i)\\big),
        \\quad K_i = \\check P G_i^T (G_i \\check P G_i^T + C R C^T)^{-1}.

    It stops when :math:`\\max |x_{i+1} - x_i| \\le` ``tol`` or after ``max_iter``
    linearisations; then P̂ from the last K, G (the Joseph form by default, as in
    :func:`ekf_update`).
    With ``max_iter=1`` this is exactly :func:`ekf_update`.

    Parameters
    ----------
    x_check, P_check, y, g, R, C, residual, joseph
        As in :func:`ekf_update`.
    G : callable
        ``G(x) -> (m, n)``: the Jacobian must be a function, as it is re-evaluated.
    tol : float
        Step-size tolerance (largest absolute change of a state component), >= 0.
    max_iter : int
        Maximum number of linearisations (>= 1).

    Returns
    -------
    IEKFUpdate
        ``(x_hat, P_hat, innovation, S, K, iterations, converged)``.

    Raises
    ------
    ValueError
        As :func:`ekf_update` (what the callables return is named ``g(x_op)``,
        ``G(x_op)``, ``residual(y, g(x_op))``), and for a ``G`` that is not callable, a
        negative or non-finite ``tol``, a ``max_iter`` that is not an integer >= 1.
    """
    _require_callable(G, "G", "G(x) returning the Jacobian (it is re-evaluated at each iterate)")
    if isinstance(max_iter, (bool, np.bool_)) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    try:
        if isinstance(tol, (bool, np.bool_, str, bytes)):    # float("0.1") and float(True) work
            raise TypeError(tol)
        tol = float(tol)
    except (TypeError, ValueError):
        raise ValueError(f"tol must be a finite number >= 0, got {tol!r}") from None
    if not np.isfinite(tol) or tol < 0:
        raise ValueError(f"tol must be a finite number >= 0, got {tol}")
    x_check, P_check, y, n, m, CRCt, residual = _update_inputs(x_check, P_check, y, g, R, C, residual)
    x_op = x_check
    converged = False
    for iteration in range(1, int(max_iter) + 1):
        Gm = _jacobian(G, x_op, "G", "x_op", (m, n))
        innovation = _innovation(residual, y, g, x_op, "x_op", m)
        GP = dot(Gm, P_check)                                         # G_i P̌
        S = innovation_covariance(GP, Gm, CRCt)                       # S_i = G_i P̌ G_iᵀ + C R Cᵀ
        K = gain(GP, S)                                               # K_i = P̌ G_iᵀ S_i⁻¹
        x_new = x_check + dot(K, innovation - dot(Gm, x_check - x_op))
        step = np.max(np.abs(x_new - x_op))
        x_op = x_new
        if step <= tol:
            converged = True
            break
    P_hat = joseph_update(P_check, K, Gm, CRCt) if as_flag(joseph, "joseph") else short_update(P_check, K, GP)
    return IEKFUpdate(x_op, P_hat, innovation, S, K, iteration, converged)
