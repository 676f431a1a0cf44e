"""Bonus of chapter 08: a nominal-state EKF, the filter the ESKF is compared with.

Here the Kalman filter estimates the full state directly,

    x = [p (3), v (3), q (4), b_a (3), b_ω (3)]   (16 numbers, q = (w, x, y, z) unit, Hamilton),

with the continuous model

    ṗ = v,   v̇ = R(q)(f − b_a) + g,   q̇ = ½ q ⊗ (0, ω − b_ω),   ḃ_a = n_ba,   ḃ_ω = n_bω,

and noises n_a (in f) and n_ω (in ω). The state is propagated with the same midpoint rule as
the ESKF; its Jacobian A = ∂ẋ/∂x gives F = I + A T. The block ∂(R(q) a)/∂q is derived in
SymPy (:func:`rotate_jacobian`, ``lambdify``). The observation is the lidar pose as
y = [p_m; q_m] with q_m's sign chosen next to q̌ (q and −q are the same rotation), so
G = [[I, 0, 0, 0, 0], [0, 0, I₄, 0, 0]]. The attitude noise σ_θ (rad, body frame) maps to the
quaternion as R_q = ¼ Ξ(q) σ_θ² Ξ(q)ᵀ, where q ⊗ (1, ½δθ) = q + ½ Ξ(q) δθ.

What the comparison teaches: four numbers for three degrees of freedom. The quaternion's
covariance is singular along q itself, the update pulls q off the unit sphere and it must
be renormalised (this module projects P accordingly, P ← N P Nᵀ with N = I − q qᵀ on the
quaternion block), and a small regulariser keeps S invertible. The ESKF's 3-vector δθ has
none of these problems.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from kalman_course.core import so3
from kalman_course.core.imu import integrate_midpoint
from kalman_course.core.linalg import gain, innovation_covariance, joseph_update, symmetrise
from kalman_course.core.observations import PoseObservations
from kalman_course.core.validation import as_matrix, as_scalar, as_vector
# the ESKF's argument checks, so that both filters accept and reject the same inputs
from kalman_course.filters.eskf import (_as_config, _as_gravity, _as_nominal, _as_observations,
                                        _gravity_against_imu, _imu_samples)

__all__ = ["rotate_jacobian", "quat_xi", "quat_omega", "continuous_jacobian", "nominal_noise_jacobian", "propagate",
           "NominalEkfResult", "run_nominal_ekf", "REGULARISER"]

#: Added to the quaternion block of the observation covariance so that S stays invertible.
REGULARISER = 1e-10


@functools.lru_cache(maxsize=None)
def _rotate_jacobian_fn():
    w, x, y, z = sp.symbols("q_w q_x q_y q_z", real=True)
    a = sp.symbols("a_1:4", real=True)
    # rotation of a by the (not necessarily unit) quaternion, homogeneous form
    R = sp.Matrix([
        [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])
    J = (R * sp.Matrix(a)).jacobian(sp.Matrix([w, x, y, z]))
    return sp.lambdify([w, x, y, z, *a], J, modules="numpy")


def rotate_jacobian(q, a) -> np.ndarray:
    """∂(R(q) a)/∂q (3, 4) for q = (w, x, y, z) (4,) and a vector a (3,) (from SymPy)."""
    q, a = _as_quaternion(q), as_vector(a, "a", 3)
    return np.asarray(_rotate_jacobian_fn()(*q, *a), dtype=float)


def _as_quaternion(q, name: str = "q") -> np.ndarray:
    """``q`` as a finite, non-zero quaternion (w, x, y, z), shape (4,)."""
    q = as_vector(q, name, 4)
    if not q.any():
        raise ValueError(f"{name} must be a non-zero quaternion (w, x, y, z), got {q}")
    return q


def quat_xi(q) -> np.ndarray:
    """Ξ(q) (4, 3) with q ⊗ (0, v) = Ξ(q) v, for q (4,)."""
    w, x, y, z = as_vector(q, "q", 4)
    return np.array([[-x, -y, -z], [w, -z, y], [z, w, -x], [-y, x, w]])


def quat_omega(v) -> np.ndarray:
    """Ω(v) (4, 4) with q ⊗ (0, v) = Ω(v) q, for v (3,)."""
    x, y, z = as_vector(v, "v", 3)
    return np.array([[0.0, -x, -y, -z], [x, 0.0, z, -y], [y, -z, 0.0, x], [z, y, -x, 0.0]])


def continuous_jacobian(q, f, w, b_a, b_w) -> np.ndarray:
    """A = ∂ẋ/∂x (16, 16) of the nominal-state model at q (4,), readings f, ω (3,) and biases (3,)."""
    q = _as_quaternion(q)
    a = as_vector(f, "f", 3) - as_vector(b_a, "b_a", 3)
    om = as_vector(w, "w", 3) - as_vector(b_w, "b_w", 3)
    A = np.zeros((16, 16))
    A[0:3, 3:6] = np.eye(3)
    A[3:6, 6:10] = rotate_jacobian(q, a)
    A[3:6, 10:13] = -so3.quat_to_matrix(q)
    A[6:10, 6:10] = 0.5 * quat_omega(om)
    A[6:10, 13:16] = -0.5 * quat_xi(q)
    return A


def nominal_noise_jacobian(q) -> np.ndarray:
    """B (16, 12) at q (4,): columns n_a, n_ω, n_ba, n_bω."""
    q = _as_quaternion(q)
    B = np.zeros((16, 12))
    B[3:6, 0:3] = so3.quat_to_matrix(q)
    B[6:10, 3:6] = 0.5 * quat_xi(q)
    B[10:13, 6:9] = np.eye(3)
    B[13:16, 9:12] = np.eye(3)
    return B


def propagate(x: np.ndarray, f0, w0, f1, w1, dt: float, g) -> np.ndarray:
    """One midpoint step of the nominal state x (16,); q is renormalised.

    ``f0``, ``w0``, ``f1``, ``w1`` (3,) are the readings at the start and end of the step,
    ``dt`` its length (s, > 0) and ``g`` (3,) gravity.
    """
    x = as_vector(x, "x", 16)
    p, v, q, b_a, b_w = x[0:3], x[3:6], _as_quaternion(x[6:10], "x[6:10]"), x[10:13], x[13:16]
    f0, f1 = as_vector(f0, "f0", 3), as_vector(f1, "f1", 3)
    w0, w1 = as_vector(w0, "w0", 3), as_vector(w1, "w1", 3)
    dt, g = as_scalar(dt, "dt"), as_vector(g, "g", 3)
    w_mean = 0.5 * (w0 + w1) - b_w
    # position and velocity by the course's one midpoint kernel; the attitude kept as q
    ps, vs, _ = integrate_midpoint(p, v, so3.quat_to_matrix(q), np.stack([f0 - b_a, f1 - b_a]), w_mean[None],
                                   np.array([dt]), g)
    q1 = so3.quat_normalise(so3.quat_multiply(q, so3.quat_exp(w_mean * dt)))
    return np.concatenate([ps[1], vs[1], q1, b_a, b_w])


def _checked_matrix(fn, label: str):
    """``fn`` wrapped so that what it returns is checked as a finite (16, 16) matrix named ``label``."""
    def checked(*args):
        return as_matrix(fn(*args), label, (16, 16))
    return checked


@dataclass(frozen=True)
class NominalEkfResult:
    """Output of :func:`run_nominal_ekf` at the update times.

    Attributes
    ----------
    t : (K,) s; position (K, 3); rotation (K, 3, 3); quaternion (K, 4);
    accel_bias, gyro_bias : (K, 3)
    P : (K, 16, 16) covariance of x
    P_pose : (K, 6, 6) covariance of [δp, δθ] (δθ in the body frame), for the pose NEES
    """

    t: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    quaternion: np.ndarray
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    P: np.ndarray
    P_pose: np.ndarray


def run_nominal_ekf(imu, initial, config="kitti_lidar", gravity=(0.0, 0.0, -9.8092), *, lidar=None,
                    start: int = 0, t_end: float | None = None, jacobian=None,
                    covariance_update=None) -> NominalEkfResult:
    """Run the nominal-state EKF on IMU samples with lidar pose updates.

    Same inputs and noise settings as :func:`kalman_course.filters.eskf.run` (the attitude prior and
    noise, given for δθ in the configuration, are mapped to the quaternion through Ξ(q));
    an observation between two IMU samples is handled the same way (interpolated reading,
    exact propagation to its time). Biases follow random walks. ``jacobian`` (q, f, w, b_a, b_w)
    -> A (16, 16) is the model's Jacobian (default :func:`continuous_jacobian`) and
    ``covariance_update`` (P, K, G, R) -> P̂ the update of P (default the Joseph form):
    chapter 08's exercise runs the filter on the learner's own.

    ``lidar`` (keyword, required) is a :class:`PoseObservations` with at least one
    observation inside the IMU span that is filtered (from ``imu.t[start]`` up to
    ``t_end``): the result holds the states at the update times.

    Raises
    ------
    ValueError
        As :func:`kalman_course.filters.eskf.run` for the IMU record, the initial state, the
        configuration and gravity; for a ``lidar`` that is missing, not a pose record or has
        no observation inside the filtered span; for a ``jacobian`` or ``covariance_update``
        that is not callable or returns something other than a finite (16, 16) matrix.
    """
    cfg = _as_config(config)
    initial = _as_nominal(initial, "initial")
    g = _as_gravity(gravity)
    for name, fn in (("jacobian", jacobian), ("covariance_update", covariance_update)):
        if fn is not None and not callable(fn):
            raise ValueError(f"{name} must be None or a callable, got {type(fn).__name__}")
    if lidar is None:
        raise ValueError("lidar must be a PoseObservations (the nominal-state EKF is corrected by pose "
                         "updates only), got None")
    t_imu, f_imu, w_imu, _ = _imu_samples(imu, start, t_end)
    _gravity_against_imu(g, initial.rotation, f_imu)
    lidar = _as_observations(lidar, "lidar", PoseObservations)
    inside = (lidar.t >= t_imu[0]) & (lidar.t <= t_imu[-1])
    if not inside.any():
        span = (f"[{lidar.t[0]:.4f}, {lidar.t[-1]:.4f}] s" if len(lidar) else "none (an empty record)")
        raise ValueError(f"lidar has no observation inside the filtered IMU span [{t_imu[0]:.4f}, "
                         f"{t_imu[-1]:.4f}] s (imu.t from start={start} up to t_end={t_end}); its times: {span}")
    model = continuous_jacobian if jacobian is None else _checked_matrix(jacobian, "jacobian(q, f, w, b_a, b_w)")
    if covariance_update is not None:
        covariance_update = _checked_matrix(covariance_update, "covariance_update(P, K, G, R)")
    dens = cfg.process_density
    prior = cfg.prior_std
    q0 = so3.matrix_to_quat(initial.rotation)
    x = np.concatenate([initial.position, initial.velocity, q0, np.zeros(6)])
    Xi = quat_xi(q0)
    P = np.zeros((16, 16))
    P[0:6, 0:6] = np.diag(prior[0:6] ** 2)
    P[6:10, 6:10] = 0.25 * Xi @ np.diag(prior[6:9] ** 2) @ Xi.T
    P[10:16, 10:16] = np.diag(prior[9:15] ** 2)
    sp_, sa_ = cfg.lidar_std[0], cfg.lidar_std[3]
    G = np.zeros((7, 16))
    G[0:3, 0:3] = np.eye(3)
    G[3:7, 6:10] = np.eye(4)
    I16 = np.eye(16)

    dens_cols = np.repeat(dens, 3)             # B Q Bᵀ = T · (B_t diag(σ²) B_tᵀ) with the T / √T scaling

    def predict(x, P, f0, w0, f1, w1, dt):
        A = model(x[6:10], f0, 0.5 * (w0 + w1), x[10:13], x[13:16])
        F = I16 + A * dt
        Bs = nominal_noise_jacobian(x[6:10]) * dens_cols
        return propagate(x, f0, w0, f1, w1, dt, g), symmetrise(F @ P @ F.T + dt * (Bs @ Bs.T))

    t, f, w = t_imu[0], f_imu[0], w_imu[0]
    lt = lidar.t
    j = int(np.searchsorted(lt, t, side="right"))
    out = []
    for k in range(1, len(t_imu)):
        while j < len(lt) and lt[j] <= t_imu[k]:
            s = (lt[j] - t_imu[k - 1]) / (t_imu[k] - t_imu[k - 1])
            f_j = (1 - s) * f_imu[k - 1] + s * f_imu[k]
            w_j = (1 - s) * w_imu[k - 1] + s * w_imu[k]
            if lt[j] > t:
                x, P = predict(x, P, f, w, f_j, w_j, lt[j] - t)
                t, f, w = lt[j], f_j, w_j
            q = x[6:10]
            q_m = so3.matrix_to_quat(lidar.rotation[j])
            if q_m @ q < 0.0:
                q_m = -q_m
            y = np.concatenate([lidar.position[j], q_m])
            Xi = quat_xi(q)
            Rn = np.zeros((7, 7))
            Rn[0:3, 0:3] = np.eye(3) * sp_ ** 2
            Rn[3:7, 3:7] = 0.25 * sa_ ** 2 * Xi @ Xi.T + REGULARISER * np.eye(4)
            GP = G @ P
            K = gain(GP, innovation_covariance(GP, G, Rn))
            x = x + K @ (y - G @ x)
            P = joseph_update(P, K, G, Rn, I16) if covariance_update is None else covariance_update(P, K, G, Rn)
            # back onto the unit sphere, and the covariance with it
            nq = np.linalg.norm(x[6:10])
            x[6:10] /= nq
            N = np.eye(16)
            N[6:10, 6:10] = (np.eye(4) - np.outer(x[6:10], x[6:10])) / nq
            P = symmetrise(N @ P @ N.T)
            out.append((t, x.copy(), P.copy()))
            j += 1
        if t_imu[k] > t:
            x, P = predict(x, P, f, w, f_imu[k], w_imu[k], t_imu[k] - t)
            t, f, w = t_imu[k], f_imu[k], w_imu[k]
    ts = np.array([o[0] for o in out])
    xs = np.array([o[1] for o in out])
    Ps = np.array([o[2] for o in out])
    pose = np.zeros((len(out), 6, 6))
    for i, (_, xi, Pi) in enumerate(out):
        J = np.zeros((6, 16))
        J[0:3, 0:3] = np.eye(3)
        J[3:6, 6:10] = 2.0 * quat_xi(xi[6:10]).T          # δθ = 2 Ξ(q)ᵀ δq
        pose[i] = J @ Pi @ J.T
    return NominalEkfResult(ts, xs[:, 0:3], so3.quat_to_matrix(xs[:, 6:10]), xs[:, 6:10], xs[:, 10:13],
                            xs[:, 13:16], Ps, pose)
