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

The second half of the module holds the chapters' reference filters:
:func:`fuse_lidar_radar` (CTRV target, lidar + radar) and :func:`run_kitti_ctrv`
(CTRV on KITTI with 1 Hz GNSS and the IMU yaw rate).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from kalman_course import symbolic
from kalman_course.filters.kf import KFUpdate
from kalman_course.core.linalg import symmetrise
from kalman_course.core.validation import as_covariance, as_matrix, as_observation_noise, as_vector

__all__ = [
    "ekf_predict", "ekf_update", "iekf_update", "IEKFUpdate", "KFUpdate",
    "wrap_angle", "radar_residual",
    "lidar_observation", "lidar_jacobian", "LIDAR_G",
    "FusionResult", "fuse_lidar_radar", "initial_ctrv_state",
    "KittiCTRVResult", "run_kitti_ctrv",
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
# angles and residuals
# ---------------------------------------------------------------------------------------

def wrap_angle(angle):
    """Wrap angles (rad) to (−π, π]; works on scalars and arrays."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped


def radar_residual(y, y_pred) -> np.ndarray:
    """Radar residual ``y − y_pred`` with the bearing difference wrapped to (−π, π].

    Without the wrap a target near the negative x axis, where the bearing jumps from π
    to −π, produces a residual of almost 2π and throws the estimate away.
    """
    e = np.asarray(y, dtype=float) - np.asarray(y_pred, dtype=float)
    e[1] = wrap_angle(e[1])
    return e


# ---------------------------------------------------------------------------------------
# the filter steps
# ---------------------------------------------------------------------------------------

def _jacobian(value, x, name: str, shape) -> np.ndarray:
    """Evaluate a Jacobian given as a callable (of x) or as a matrix, and validate it."""
    J = value(x) if callable(value) else value
    return as_matrix(J if isinstance(J, np.ndarray) else np.asarray(J, dtype=float), name, shape)


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
        If ``f`` is not callable, a shape does not match, or a covariance is not symmetric.
    """
    if not callable(f):
        raise ValueError("f must be a callable f(x) returning the predicted state")
    x_hat = as_vector(x_hat, "x_hat")
    n = x_hat.shape[0]
    P_hat = as_covariance(P_hat, "P_hat", n)
    Fm = _jacobian(F, x_hat, "F", (n, n))
    if B is None:
        BQBt = as_covariance(Q, "Q", n)
    else:
        Bm = _jacobian(B, x_hat, "B", (n, None))
        BQBt = Bm @ as_covariance(Q, "Q", Bm.shape[1]) @ Bm.T
    x_check = as_vector(np.asarray(f(x_hat), dtype=float), "f(x_hat)", n)
    return x_check, symmetrise(Fm @ P_hat @ Fm.T + BQBt)


def _gain(P_check, G, CRCt):
    GP = G @ P_check
    S = GP @ G.T + CRCt
    K = np.linalg.solve(S, GP).T                     # K = P̌ Gᵀ S⁻¹ (S and P̌ symmetric)
    return S, K


def _posterior_cov(P_check, G, K, CRCt, joseph):
    if joseph:
        I_KG = np.eye(P_check.shape[0]) - K @ G
        return symmetrise(I_KG @ P_check @ I_KG.T + K @ CRCt @ K.T)
    return symmetrise(P_check - K @ (G @ P_check))


def _update_inputs(x_check, P_check, y, R, C, residual):
    x_check = as_vector(x_check, "x_check")
    n = x_check.shape[0]
    P_check = as_covariance(P_check, "P_check", n)
    y = as_vector(y, "y")
    m = y.shape[0]
    CRCt = as_observation_noise(R, C, m)
    if residual is None:
        residual = np.subtract
    elif not callable(residual):
        raise ValueError("residual must be a callable residual(y, y_pred) or None")
    return x_check, P_check, y, n, m, CRCt, residual


def _predicted_measurement(g, x, m):
    return as_vector(np.asarray(g(x), dtype=float), "g(x)", m)


def ekf_update(x_check, P_check, y, g: Callable, G, R, C=None, residual=None, joseph=False):
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
    joseph : bool, default False
        Joseph form of the covariance update.

    Returns
    -------
    KFUpdate
        ``(x_hat, P_hat, innovation, S, K)``.
    """
    if not callable(g):
        raise ValueError("g must be a callable g(x) returning the predicted measurement")
    x_check, P_check, y, n, m, CRCt, residual = _update_inputs(x_check, P_check, y, R, C, residual)
    Gm = _jacobian(G, x_check, "G", (m, n))
    innovation = np.asarray(residual(y, _predicted_measurement(g, x_check, m)), dtype=float)
    S, K = _gain(P_check, Gm, CRCt)
    x_hat = x_check + K @ innovation
    return KFUpdate(x_hat, _posterior_cov(P_check, Gm, K, CRCt, bool(joseph)), innovation, S, K)


def iekf_update(x_check, P_check, y, g: Callable, G: Callable, R, C=None, residual=None,
                tol: float = 1e-9, max_iter: int = 20, joseph=False) -> IEKFUpdate:
    """Iterated EKF update (Gauss–Newton on the measurement).

    Starting from :math:`x_0 = \\check x`, each iteration linearises g at the newest
    iterate :math:`x_i` and sets

    .. math::

        x_{i+1} = \\check x + K_i \\big(r(y, g(x_i)) - G_i (\\check x - x_i)\\big),
        \\quad K_i = \\check P G_i^T (G_i \\check P G_i^T + C R C^T)^{-1}.

    It stops when :math:`\\max |x_{i+1} - x_i| \\le` ``tol`` or after ``max_iter``
    linearisations; then :math:`\\hat P = (I - K_i G_i) \\check P` with the last K, G.
    With ``max_iter=1`` this is exactly :func:`ekf_update`.

    Parameters
    ----------
    x_check, P_check, y, g, R, C, residual, joseph
        As in :func:`ekf_update`.
    G : callable
        ``G(x) -> (m, n)``: the Jacobian must be a function, as it is re-evaluated.
    tol : float
        Step-size tolerance (largest absolute change of a state component).
    max_iter : int
        Maximum number of linearisations (>= 1).

    Returns
    -------
    IEKFUpdate
        ``(x_hat, P_hat, innovation, S, K, iterations, converged)``.
    """
    if not callable(g) or not callable(G):
        raise ValueError("g and G must be callables of the state (G is re-evaluated at each iterate)")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    tol = float(tol)
    if not np.isfinite(tol) or tol < 0:
        raise ValueError(f"tol must be a finite number >= 0, got {tol}")
    x_check, P_check, y, n, m, CRCt, residual = _update_inputs(x_check, P_check, y, R, C, residual)
    x_op = x_check
    converged = False
    for iteration in range(1, int(max_iter) + 1):
        Gm = _jacobian(G, x_op, "G", (m, n))
        innovation = np.asarray(residual(y, _predicted_measurement(g, x_op, m)), dtype=float)
        S, K = _gain(P_check, Gm, CRCt)
        x_new = x_check + K @ (innovation - Gm @ (x_check - x_op))
        step = np.max(np.abs(x_new - x_op))
        x_op = x_new
        if step <= tol:
            converged = True
            break
    P_hat = _posterior_cov(P_check, Gm, K, CRCt, bool(joseph))
    return IEKFUpdate(x_op, P_hat, innovation, S, K, iteration, converged)


# ---------------------------------------------------------------------------------------
# chapter 05: lidar + radar fusion of a CTRV target
# ---------------------------------------------------------------------------------------

#: Lidar observation Jacobian for the CTRV state: it sees p_x and p_y.
LIDAR_G = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0]])


def lidar_observation(x) -> np.ndarray:
    """Lidar measurement function for the CTRV state: [p_x, p_y]."""
    return np.asarray(x, dtype=float)[:2].copy()


def lidar_jacobian(x) -> np.ndarray:
    """Lidar Jacobian (2, 5), constant: the lidar observation is linear."""
    return LIDAR_G


def initial_ctrv_state(z_lidar, R_lidar, sigma_v=5.0, sigma_yaw=np.pi, sigma_yaw_rate=0.5):
    """Prior from a first lidar fix: position measured, speed, heading and turn rate unknown.

    Returns ``x0 = [z_x, z_y, 0, 0, 0]`` and ``P0 = diag(R_lidar, σ_v², σ_ψ², σ_ω²)``.
    """
    x0 = np.array([z_lidar[0], z_lidar[1], 0.0, 0.0, 0.0])
    P0 = np.zeros((5, 5))
    P0[:2, :2] = R_lidar
    P0[2, 2], P0[3, 3], P0[4, 4] = sigma_v**2, sigma_yaw**2, sigma_yaw_rate**2
    return x0, P0


@dataclass(frozen=True, eq=False)
class FusionResult:
    """A lidar + radar CTRV run (one row per measurement of the scenario).

    Attributes
    ----------
    t : ndarray, shape (N,)
    x_hat : ndarray, shape (N, 5)
        Posterior CTRV states [p_x, p_y, v, ψ, ω].
    P_hat : ndarray, shape (N, 5, 5)
    truth : ndarray, shape (N, 5)
    rmse : dict
        RMSE of p_x, p_y (m) and v_x, v_y (m/s), as in the seed article.
    iterations : ndarray of int, shape (N,)
        Linearisations per update (all 1 for the EKF).
    """

    t: np.ndarray
    x_hat: np.ndarray
    P_hat: np.ndarray
    truth: np.ndarray
    rmse: dict
    iterations: np.ndarray

    def cartesian(self, states=None) -> np.ndarray:
        """[p_x, p_y, v_x, v_y] of ``states`` (default: the estimates), shape (N, 4)."""
        s = self.x_hat if states is None else states
        return np.column_stack([s[:, 0], s[:, 1], s[:, 2] * np.cos(s[:, 3]), s[:, 2] * np.sin(s[:, 3])])


def cartesian_rmse(estimate_cart, truth_cart) -> dict:
    """RMSE per component of [p_x, p_y, v_x, v_y] arrays of shape (N, 4)."""
    err = np.sqrt(np.mean((np.asarray(estimate_cart) - np.asarray(truth_cart)) ** 2, axis=0))
    return dict(zip(("px", "py", "vx", "vy"), (float(e) for e in err)))


def fuse_lidar_radar(scenario, sigma_a=None, sigma_yaw_acc=None, *, use_lidar=True, use_radar=True,
                     iterated=False, max_iter=20, joseph=True) -> FusionResult:
    """Reference CTRV EKF (or IEKF) fusing the lidar and radar of a ``ctrv_lidar_radar`` scenario.

    The prior comes from the first lidar fix (:func:`initial_ctrv_state`). Each
    measurement is a prediction over ``scenario.dt`` (CTRV, derived Jacobians, process
    noise :math:`B \\, \\mathrm{diag}(\\sigma_a^2, \\sigma_{\\ddot\\psi}^2) B^T`) and an
    update: linear for lidar, linearised (or iterated) radar with the wrapped residual.
    Sensors switched off still predict through their time steps.

    Parameters
    ----------
    scenario : CTRVScenario
    sigma_a, sigma_yaw_acc : float, optional
        Process noise; default the scenario's own values.
    use_lidar, use_radar : bool
        Which sensors to fuse.
    iterated : bool
        Use :func:`iekf_update` for the radar.
    joseph : bool
        Joseph form for the covariance updates.
    """
    sigma_a = scenario.sigma_a if sigma_a is None else float(sigma_a)
    sigma_yaw_acc = scenario.sigma_yaw_acc if sigma_yaw_acc is None else float(sigma_yaw_acc)
    Qw = np.diag([sigma_a**2, sigma_yaw_acc**2])
    dt = scenario.dt
    x, P = initial_ctrv_state(scenario.lidar_z[0], scenario.R_lidar)
    measurements = list(scenario.measurements())
    N = len(measurements)
    xs, Ps, its = np.empty((N, 5)), np.empty((N, 5, 5)), np.ones(N, dtype=int)

    def f(state):
        return symbolic.ctrv_step(state, dt)

    def F(state):
        return symbolic.ctrv_jacobian(state, dt)

    def B(state):
        return symbolic.ctrv_noise_jacobian(state, dt)

    for k, meas in enumerate(measurements):
        if k > 0:
            x, P = ekf_predict(x, P, f, F, Qw, B)
        if meas.sensor == "lidar" and use_lidar and k > 0:
            x, P = ekf_update(x, P, meas.z, lidar_observation, LIDAR_G, meas.R, joseph=joseph)[:2]
        elif meas.sensor == "radar" and use_radar:
            if iterated:
                res = iekf_update(x, P, meas.z, symbolic.radar_observation, symbolic.radar_jacobian,
                                  meas.R, residual=radar_residual, max_iter=max_iter, joseph=joseph)
                x, P, its[k] = res.x_hat, res.P_hat, res.iterations
            else:
                x, P = ekf_update(x, P, meas.z, symbolic.radar_observation, symbolic.radar_jacobian,
                                  meas.R, residual=radar_residual, joseph=joseph)[:2]
        xs[k], Ps[k] = x, P
    result = FusionResult(scenario.t.copy(), xs, Ps, scenario.x.copy(), {}, its)
    rmse = cartesian_rmse(result.cartesian(), result.cartesian(scenario.x))
    return FusionResult(result.t, xs, Ps, result.truth, rmse, its)


# ---------------------------------------------------------------------------------------
# chapter 05: CTRV on KITTI, GNSS at 1 Hz, IMU yaw rate
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class KittiCTRVResult:
    """A CTRV EKF run on a KITTI excerpt.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Filter times (the IMU samples used), s.
    x_hat : ndarray, shape (N, 5)
        [p_x (east, m), p_y (north, m), v (m/s), ψ (rad, unwrapped), ω (rad/s)].
    P_hat : ndarray, shape (N, 5, 5)
    truth_xy : ndarray, shape (N, 2)
        True horizontal position at ``t``.
    gnss_rmse, ekf_rmse : float
        Horizontal position RMSE of the noisy GNSS fixes and of the filter at the fix
        times, m.
    ekf_rmse_all : float
        Horizontal position RMSE of the filter at every filter time, m.
    """

    t: np.ndarray
    x_hat: np.ndarray
    P_hat: np.ndarray
    truth_xy: np.ndarray
    gnss_rmse: float
    ekf_rmse: float
    ekf_rmse_all: float


def _yaw_of(rotation) -> np.ndarray:
    return np.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])


def run_kitti_ctrv(excerpt, *, rate_hz=10.0, sigma_a=3.0, sigma_yaw_acc=0.5, sigma_gyro=0.02,
                   sigma_gnss=None) -> KittiCTRVResult:
    """A CTRV EKF on a KITTI excerpt: noisy 1 Hz GNSS positions and the IMU yaw rate.

    The filter runs at ``rate_hz`` (the IMU decimated): every step predicts with CTRV and
    updates the turn rate ω with the gyro's z reading (σ ``sigma_gyro`` rad/s); at each
    GNSS fix it also updates p_x, p_y (σ = the excerpt's GNSS noise). The prior comes from
    the first two fixes alone: the second fix's position, and speed and heading from the
    difference of the two (with their propagated uncertainty); the filter starts there.
    """
    imu, gnss, truth = excerpt.imu, excerpt.gnss, excerpt.truth
    sigma_gnss = gnss.sigma if sigma_gnss is None else float(sigma_gnss)
    # the prior comes from the first two fixes: position, and speed and heading from their difference
    i0 = int(np.searchsorted(gnss.t, max(truth.t[0], imu.t[0])))
    p1, p2 = gnss.position_noisy[i0, :2], gnss.position_noisy[i0 + 1, :2]
    dt_fix = gnss.t[i0 + 1] - gnss.t[i0]
    speed = float(np.linalg.norm(p2 - p1) / dt_fix)
    var_v = 2.0 * sigma_gnss**2 / dt_fix**2 + (sigma_a * dt_fix) ** 2
    var_yaw = min(var_v / max(speed, 1e-3) ** 2, np.pi**2)
    t0, t_end = gnss.t[i0 + 1], min(imu.t[-1], truth.t[-1])
    t = np.arange(t0, t_end, 1.0 / rate_hz)
    omega_z = np.interp(t, imu.t, imu.angular_rate[:, 2])
    fix_index = np.searchsorted(t, gnss.t - 0.5 / rate_hz)      # the filter step nearest each fix
    fixes = {int(k): gnss.position_noisy[i, :2] for i, k in enumerate(fix_index)
             if k < len(t) and abs(t[k] - gnss.t[i]) <= 0.5 / rate_hz}
    Qw = np.diag([sigma_a**2, sigma_yaw_acc**2])
    R_gnss = sigma_gnss**2 * np.eye(2)
    R_gyro = np.array([[sigma_gyro**2]])
    G_gyro = np.array([[0.0, 0.0, 0.0, 0.0, 1.0]])
    x = np.array([p2[0], p2[1], speed, np.arctan2(*(p2 - p1)[::-1]), omega_z[0]])
    P = np.diag([sigma_gnss**2, sigma_gnss**2, var_v, var_yaw, sigma_gyro**2])
    N = len(t)
    xs, Ps = np.empty((N, 5)), np.empty((N, 5, 5))
    for k in range(N):
        if k > 0:
            T = t[k] - t[k - 1]
            x, P = ekf_predict(x, P, lambda s: symbolic.ctrv_step(s, T), symbolic.ctrv_jacobian(x, T),
                               Qw, symbolic.ctrv_noise_jacobian(x, T))
        x, P = ekf_update(x, P, omega_z[k:k + 1], lambda s: s[4:5], G_gyro, R_gyro, joseph=True)[:2]
        if k in fixes and k > 0:
            x, P = ekf_update(x, P, fixes[k], lidar_observation, LIDAR_G, R_gnss, joseph=True)[:2]
        xs[k], Ps[k] = x, P
    truth_xy = truth.interpolate(t).position[:, :2]
    fix_steps = np.array(sorted(fixes))
    raw = np.array([fixes[k] for k in fix_steps])
    gnss_rmse = float(np.sqrt(np.mean(np.sum((raw - truth_xy[fix_steps]) ** 2, axis=1))))
    ekf_rmse = float(np.sqrt(np.mean(np.sum((xs[fix_steps, :2] - truth_xy[fix_steps]) ** 2, axis=1))))
    ekf_all = float(np.sqrt(np.mean(np.sum((xs[:, :2] - truth_xy) ** 2, axis=1))))
    return KittiCTRVResult(t, xs, Ps, truth_xy, gnss_rmse, ekf_rmse, ekf_all)


# ---------------------------------------------------------------------------------------
# chapter 06: precise range–bearing to beacons along a KITTI trajectory
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class BeaconScenario:
    """A car on a KITTI excerpt measuring range and bearing to the nearest beacons.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Measurement times, s.
    truth : ndarray, shape (N, 4)
        True planar CV state [p_x, p_y, v_x, v_y] (m, m/s) from the KITTI ground truth.
    beacons : ndarray, shape (B, 2)
        Beacon positions, m.
    nearest : ndarray of int, shape (N, n_beacons)
        Indices of the beacons measured at each time.
    z : ndarray, shape (N, 2 n_beacons)
        [range (m), bearing (rad, world frame, wrapped)] for each measured beacon.
    R : ndarray, shape (2 n_beacons, 2 n_beacons)
        Measurement noise covariance.
    x0, P0 : ndarray, shapes (4,), (4, 4)
        The filter's prior at t[0]: truth plus a draw from N(0, P0).
    """

    name: str
    t: np.ndarray
    truth: np.ndarray
    beacons: np.ndarray
    nearest: np.ndarray
    z: np.ndarray
    R: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    seed: int


def kitti_beacons(name="turns", seed=1, *, spacing=15.0, offset=4.0, rate_hz=1.0, sigma_range=0.05,
                  sigma_bearing_deg=0.5, n_beacons=2, sigma_p0=3.0, sigma_v0=2.0) -> BeaconScenario:
    """Beacons every ``spacing`` m of the path, ``offset`` m to its left; range–bearing to the nearest.

    Small offsets with precise measurements make the observation strongly nonlinear over
    the prior's uncertainty (the chapter 06 case where the IEKF wins); large offsets (say
    100 m) make it nearly linear (no difference). Noise is drawn from
    ``default_rng(seed)``: measurement noise (N, 2 n_beacons) then the prior's error (4,).
    """
    from kalman_course.data import load_kitti

    truth = load_kitti(name).truth
    t = np.arange(truth.t[0], truth.t[-1], 1.0 / rate_hz)
    traj = truth.interpolate(t)
    states = np.column_stack([traj.position[:, :2], traj.velocity[:, :2]])
    path = truth.position[:, :2]
    along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    marks = np.arange(0.0, along[-1], spacing)
    k = np.clip(np.searchsorted(along, marks), 0, len(along) - 1)
    heading = truth.velocity[k, :2] / np.maximum(np.linalg.norm(truth.velocity[k, :2], axis=1), 1e-3)[:, None]
    left = np.column_stack([-heading[:, 1], heading[:, 0]])
    beacons = np.column_stack([np.interp(marks, along, path[:, 0]), np.interp(marks, along, path[:, 1])])
    beacons = beacons + offset * left
    nearest = np.argsort(np.linalg.norm(beacons[None, :, :] - states[:, None, :2], axis=2), axis=1)[:, :n_beacons]
    rng = np.random.default_rng(seed)
    sig = np.tile([sigma_range, np.deg2rad(sigma_bearing_deg)], n_beacons)
    z = np.array([beacon_observation(beacons[idx])(s) for s, idx in zip(states, nearest)])
    z = z + sig * rng.standard_normal(z.shape)
    z[:, 1::2] = wrap_angle(z[:, 1::2])
    P0 = np.diag([sigma_p0**2, sigma_p0**2, sigma_v0**2, sigma_v0**2])
    x0 = states[0] + np.sqrt(np.diag(P0)) * rng.standard_normal(4)
    return BeaconScenario(name, t, states, beacons, nearest, z, np.diag(sig**2), x0, P0, int(seed))


def beacon_observation(beacons) -> Callable:
    """g(x) = [range, bearing] to each beacon (rows of ``beacons``), for a CV state [p, v].

    Built from the SymPy radar model (its first two rows, with the beacon as origin).
    """
    beacons = np.atleast_2d(np.asarray(beacons, dtype=float))

    def g(x):
        out = np.empty(2 * len(beacons))
        for i, b in enumerate(beacons):
            out[2 * i:2 * i + 2] = symbolic.radar_observation(np.r_[x[:2] - b, 0.0, 0.0], "cv")[:2]
        return out

    return g


def beacon_jacobian(beacons) -> Callable:
    """G(x) = ∂g/∂x, shape (2 B, 4), of :func:`beacon_observation` (SymPy-derived rows)."""
    beacons = np.atleast_2d(np.asarray(beacons, dtype=float))

    def G(x):
        out = np.zeros((2 * len(beacons), 4))
        for i, b in enumerate(beacons):
            out[2 * i:2 * i + 2, :2] = symbolic.radar_jacobian(np.r_[x[:2] - b, 0.0, 0.0], "cv")[:2, :2]
        return out

    return G


def bearings_residual(y, y_pred) -> np.ndarray:
    """Residual of stacked [range, bearing] pairs, each bearing difference wrapped."""
    e = np.asarray(y, dtype=float) - np.asarray(y_pred, dtype=float)
    e[1::2] = wrap_angle(e[1::2])
    return e


@dataclass(frozen=True, eq=False)
class BeaconResult:
    """An EKF or IEKF run on a :class:`BeaconScenario`.

    Attributes
    ----------
    x_hat, P_hat : ndarray, shapes (N, 4), (N, 4, 4)
    position_rmse : float
        Horizontal position RMSE, m.
    nees : ndarray, shape (N,)
        NEES of the full state (4 degrees of freedom) at each step.
    iterations : ndarray of int, shape (N,)
    """

    x_hat: np.ndarray
    P_hat: np.ndarray
    position_rmse: float
    nees: np.ndarray
    iterations: np.ndarray

    @property
    def mean_nees(self) -> float:
        """Mean NEES over the run (4 for a consistent filter)."""
        return float(np.mean(self.nees))


def run_beacon_filter(scenario: BeaconScenario, *, iterated=False, sigma_a=2.0, max_iter=20,
                      tol=1e-6) -> BeaconResult:
    """CV EKF (or IEKF) with range–bearing updates to the nearest beacons, Joseph form."""
    from kalman_course.evaluation.metrics import nees

    x, P = scenario.x0.copy(), scenario.P0.copy()
    N = len(scenario.t)
    xs, Ps, its = np.empty((N, 4)), np.empty((N, 4, 4)), np.ones(N, dtype=int)
    for k in range(N):
        if k > 0:
            T = scenario.t[k] - scenario.t[k - 1]
            F = symbolic.cv_transition(T, 2)
            x, P = ekf_predict(x, P, lambda s: F @ s, F, symbolic.cv_process_noise(T, sigma_a, 2))
        b = scenario.beacons[scenario.nearest[k]]
        g, G = beacon_observation(b), beacon_jacobian(b)
        if iterated:
            res = iekf_update(x, P, scenario.z[k], g, G, scenario.R, residual=bearings_residual,
                              tol=tol, max_iter=max_iter, joseph=True)
            its[k] = res.iterations
        else:
            res = ekf_update(x, P, scenario.z[k], g, G, scenario.R, residual=bearings_residual, joseph=True)
        x, P = res.x_hat, res.P_hat
        xs[k], Ps[k] = x, P
    err = xs - scenario.truth
    rmse = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))))
    return BeaconResult(xs, Ps, rmse, nees(err, Ps), its)


__all__ += ["BeaconScenario", "kitti_beacons", "beacon_observation", "beacon_jacobian",
            "bearings_residual", "BeaconResult", "run_beacon_filter", "cartesian_rmse"]
