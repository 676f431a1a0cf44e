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
from kalman_course.core.validation import as_int, as_matrix, as_rotation, as_vector

__all__ = ["NavState", "NavTrajectory", "integrate_midpoint", "midpoint_step", "dead_reckon"]


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


def _seconds(dt) -> float:
    """``dt`` as a finite positive float; a string, a bool or an array is a ValueError."""
    try:
        ok = (not isinstance(dt, (bool, np.bool_, str, bytes)) and np.ndim(dt) == 0
              and not np.iscomplexobj(dt) and np.isfinite(float(dt)) and float(dt) > 0.0)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    return float(dt)


def _check_state(state: NavState, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    for field in ("position", "velocity", "rotation"):
        if not hasattr(state, field):
            raise ValueError(f"{name} must have position (3,), velocity (3,) and rotation (3, 3); "
                             f"missing {field!r}")
    p = as_vector(state.position, f"{name}.position", 3)
    v = as_vector(state.velocity, f"{name}.velocity", 3)
    R = as_rotation(state.rotation, f"{name}.rotation")
    return p, v, R


def integrate_midpoint(position, velocity, rotation, a, w, dt, gravity):
    """Midpoint mechanisation over n steps, unvalidated: p, v, R at the n + 1 nodes.

    The one implementation of the lecture's midpoint integration; :func:`midpoint_step`,
    :func:`dead_reckon` and the ESKF's nominal propagation call it after validating their
    inputs. Per step k, with T = dt[k]:

    R_{k+1} = R_k Exp(w_k T);  â_k = R_k a_k + g;  v_{k+1} = v_k + ½(â_k + â_{k+1}) T;
    p_{k+1} = p_k + v_k T + ¼(â_k + â_{k+1}) T².

    Parameters
    ----------
    position, velocity : numpy.ndarray, shape (3,)
        p and v at the first node (navigation frame).
    rotation : numpy.ndarray, shape (3, 3)
        R = R_nb at the first node.
    a : numpy.ndarray, shape (n + 1, 3)
        Bias-corrected specific force f − b_a at each node, body frame, m/s².
    w : numpy.ndarray, shape (n, 3)
        Each step's bias-corrected mean rate ½(ω_k + ω_{k+1}) − b_ω, body frame, rad/s.
    dt : numpy.ndarray, shape (n,)
        Step lengths, s.
    gravity : numpy.ndarray, shape (3,)
        g in the navigation frame, m/s².

    Returns
    -------
    positions, velocities : numpy.ndarray, shape (n + 1, 3)
    rotations : numpy.ndarray, shape (n + 1, 3, 3)
    """
    n = len(dt)
    dtc = dt[:, None]
    steps = so3.exp(w * dtc, check=False)
    Rs = np.empty((n + 1, 3, 3))
    Rs[0] = rotation
    for k, step in enumerate(steps):
        np.dot(Rs[k], step, out=Rs[k + 1])
    acc = np.matmul(Rs, a[:, :, None])[:, :, 0]
    acc += gravity
    dv = acc[:-1] + acc[1:]
    dv *= 0.5 * dtc                         # ½(â_k + â_{k+1}) T
    vs = np.empty((n + 1, 3))
    vs[0] = 0.0
    np.cumsum(dv, axis=0, out=vs[1:])
    vs += velocity
    dp = vs[:-1] + 0.5 * dv
    dp *= dtc                               # v_k T + ¼(â_k + â_{k+1}) T²
    ps = np.empty((n + 1, 3))
    ps[0] = 0.0
    np.cumsum(dp, axis=0, out=ps[1:])
    ps += position
    return ps, vs, Rs


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
    dt = _seconds(dt)
    ps, vs, Rs = integrate_midpoint(p, v, R, np.stack([f0 - b_a, f1 - b_a]), (0.5 * (w0 + w1) - b_w)[None, :],
                                    np.array([dt]), g)
    return NavState(ps[1], vs[1], Rs[1])


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
    sl = slice(as_int(start, "start"), as_int(stop, "stop", allow_none=True))
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

    p, v, R = integrate_midpoint(p0, v0, R0, f - b_a, 0.5 * (w[:-1] + w[1:]) - b_w, dt, g)
    return NavTrajectory(t.copy(), p, v, R)
