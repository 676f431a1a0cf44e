"""Strapdown IMU mechanisation with midpoint integration.

The navigation state is position p (m), velocity v (m/s) and attitude R_nb (body → nav).
Between two IMU samples k and k+1, taken ``dt = t[k+1] − t[k]`` seconds apart, the
midpoint scheme of chapter 07 is

    ω̄   = ½(ω_k + ω_{k+1}) − b_ω                      mean body angular rate (rad/s)
    R_{k+1} = R_k Exp(ω̄ dt)                           attitude
    a_k  = R_k (f_k − b_a) + g                          nav-frame acceleration (m/s²)
    ā    = ½(a_k + a_{k+1})                            (a_{k+1} uses R_{k+1})
    v_{k+1} = v_k + ā dt
    p_{k+1} = p_k + v_k dt + ½ ā dt²

with f the specific force and ω the angular rate measured in the body frame, b_a and b_ω
the accelerometer and gyroscope biases, and g the gravity vector in the navigation frame
(for KITTI g = (0, 0, −9.8092) m/s², z up). Each step uses its own dt, because real IMU
timestamps are irregular.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core import so3
from kalman_course.core.validation import as_matrix, as_vector

__all__ = ["NavState", "NavTrajectory", "midpoint_step", "dead_reckon"]


@dataclass(frozen=True)
class NavState:
    """One navigation state.

    Attributes
    ----------
    position : numpy.ndarray, shape (3,)
        p, position of the body origin in the navigation frame, m.
    velocity : numpy.ndarray, shape (3,)
        v, velocity in the navigation frame, m/s.
    rotation : numpy.ndarray, shape (3, 3)
        R_nb, attitude mapping body-frame vectors to the navigation frame.
    """

    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray


@dataclass(frozen=True)
class NavTrajectory:
    """A sequence of navigation states, one per IMU sample.

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        Sample times, s.
    position : numpy.ndarray, shape (N, 3)
        Positions in the navigation frame, m.
    velocity : numpy.ndarray, shape (N, 3)
        Velocities in the navigation frame, m/s.
    rotation : numpy.ndarray, shape (N, 3, 3)
        Attitudes R_nb.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray

    def state(self, k: int) -> NavState:
        """The state at sample ``k`` (negative indices count from the end)."""
        return NavState(self.position[k].copy(), self.velocity[k].copy(), self.rotation[k].copy())

    def __len__(self) -> int:
        return len(self.t)


def _bias(value, name: str) -> np.ndarray:
    return np.zeros(3) if value is None else as_vector(value, name, 3)


def _check_state(state: NavState, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    for field in ("position", "velocity", "rotation"):
        if not hasattr(state, field):
            raise ValueError(f"{name} must have position (3,), velocity (3,) and rotation (3, 3); "
                             f"missing {field!r}")
    p = as_vector(state.position, f"{name}.position", 3)
    v = as_vector(state.velocity, f"{name}.velocity", 3)
    R = as_matrix(state.rotation, f"{name}.rotation", (3, 3))
    if not so3.is_rotation(R, tol=1e-6):
        raise ValueError(f"{name}.rotation must be a rotation matrix (RᵀR = I, det R = +1)")
    return p, v, R


def midpoint_step(state: NavState, f0, w0, f1, w1, dt: float, gravity,
                  accel_bias=None, gyro_bias=None) -> NavState:
    """Propagate one navigation state over one IMU interval with midpoint integration.

    Parameters
    ----------
    state : NavState
        State at the first sample, time t_k.
    f0, f1 : array_like, shape (3,)
        Specific force measured at t_k and t_{k+1}, body frame, m/s².
    w0, w1 : array_like, shape (3,)
        Angular rate measured at t_k and t_{k+1}, body frame, rad/s.
    dt : float
        t_{k+1} − t_k, s (> 0).
    gravity : array_like, shape (3,)
        Gravity g in the navigation frame, m/s² (for example (0, 0, −9.81)).
    accel_bias, gyro_bias : array_like, shape (3,), optional
        b_a (m/s²) and b_ω (rad/s), subtracted from the readings; zero if omitted.

    Returns
    -------
    NavState
        The state at t_{k+1}.
    """
    p, v, R = _check_state(state, "state")
    f0, f1 = as_vector(f0, "f0", 3), as_vector(f1, "f1", 3)
    w0, w1 = as_vector(w0, "w0", 3), as_vector(w1, "w1", 3)
    g = as_vector(gravity, "gravity", 3)
    b_a, b_w = _bias(accel_bias, "accel_bias"), _bias(gyro_bias, "gyro_bias")
    dt = float(dt)
    if not np.isfinite(dt) or dt <= 0.0:
        raise ValueError(f"dt must be a positive number of seconds, got {dt}")
    w_mean = 0.5 * (w0 + w1) - b_w
    R1 = R @ so3.exp(w_mean * dt)
    a0 = R @ (f0 - b_a) + g
    a1 = R1 @ (f1 - b_a) + g
    a_mean = 0.5 * (a0 + a1)
    v1 = v + a_mean * dt
    p1 = p + v * dt + 0.5 * a_mean * dt * dt
    return NavState(p1, v1, R1)


def dead_reckon(imu, initial_state: NavState, gravity, accel_bias=None, gyro_bias=None,
                start: int = 0, stop: int | None = None) -> NavTrajectory:
    """Integrate IMU samples from an initial state (pure dead reckoning, no corrections).

    Parameters
    ----------
    imu : object
        Anything with attributes ``t`` (N,) in s (strictly increasing), ``specific_force``
        (N, 3) in m/s² and ``angular_rate`` (N, 3) in rad/s, body frame; for example
        ``load_kitti("turns").imu`` or a synthetic IMU trajectory's ``imu``.
    initial_state : NavState
        The state at ``imu.t[start]``.
    gravity : array_like, shape (3,)
        Gravity in the navigation frame, m/s².
    accel_bias, gyro_bias : array_like, shape (3,), optional
        Constant biases b_a (m/s²) and b_ω (rad/s) subtracted from every reading.
    start, stop : int, optional
        Integrate samples ``start .. stop−1`` (Python slice semantics; default: all).

    Returns
    -------
    NavTrajectory
        States at ``imu.t[start:stop]``; the first is ``initial_state``.
    """
    for field in ("t", "specific_force", "angular_rate"):
        if not hasattr(imu, field):
            raise ValueError(f"imu must have t (N,), specific_force (N, 3) and angular_rate (N, 3); "
                             f"missing {field!r}")
    t_all = as_vector(imu.t, "imu.t")
    n_all = len(t_all)
    f_all = as_matrix(imu.specific_force, "imu.specific_force", (n_all, 3))
    w_all = as_matrix(imu.angular_rate, "imu.angular_rate", (n_all, 3))
    sl = slice(start, stop)
    t, f, w = t_all[sl], f_all[sl], w_all[sl]
    if len(t) == 0:
        raise ValueError(f"start={start}, stop={stop} select no samples of imu (it has {n_all})")
    dt = np.diff(t)
    if np.any(dt <= 0.0):
        k = int(np.argmax(dt <= 0.0))
        raise ValueError(f"imu.t must be strictly increasing; t[{k + 1}] <= t[{k}] after slicing")
    p0, v0, R0 = _check_state(initial_state, "initial_state")
    g = as_vector(gravity, "gravity", 3)
    b_a, b_w = _bias(accel_bias, "accel_bias"), _bias(gyro_bias, "gyro_bias")

    n = len(t)
    steps = so3.exp((0.5 * (w[:-1] + w[1:]) - b_w) * dt[:, None])
    R = np.empty((n, 3, 3))
    R[0] = R0
    for k in range(n - 1):
        R[k + 1] = R[k] @ steps[k]
    a = np.einsum("kij,kj->ki", R, f - b_a) + g
    a_mean = 0.5 * (a[:-1] + a[1:])
    v = np.empty((n, 3))
    v[0] = v0
    v[1:] = v0 + np.cumsum(a_mean * dt[:, None], axis=0)
    p = np.empty((n, 3))
    p[0] = p0
    p[1:] = p0 + np.cumsum(v[:-1] * dt[:, None] + 0.5 * a_mean * (dt * dt)[:, None], axis=0)
    return NavTrajectory(t.copy(), p, v, R)
