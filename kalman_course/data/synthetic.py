"""Seeded synthetic scenarios with exact ground truth.

Every generator takes a ``seed`` and draws all of its randomness from
``numpy.random.default_rng(seed)`` in a documented order, so a scenario is fully
determined by its arguments.

- :func:`random_walk_1d`: a scalar random walk observed with noise (chapter 03);
- :func:`cv_target`: a constant-velocity target in 1–3 dimensions observed in position;
- :func:`imu_trajectory`: a vehicle-like 3-D trajectory with the IMU readings that
  reproduce it exactly under the course's midpoint mechanisation (chapters 07–09).

The chapter 05 lidar + radar scenario is built on the CTRV model and radar h(x) of
:mod:`kalman_course.symbolic`, a layer the data layer may not import, so it lives in
:mod:`kalman_course.chapters.lidar_radar` (``ctrv_lidar_radar``).
"""

from __future__ import annotations

from dataclasses import dataclass
import numpy as np

from kalman_course.core import so3
from kalman_course.data.kitti import ImuData
from kalman_course.core.imu import NavState, dead_reckon
from kalman_course.core.validation import as_real, as_scalar, as_seed, as_vector

__all__ = ["RandomWalk1D", "random_walk_1d", "CVTarget", "cv_target", "ImuScenario", "imu_trajectory"]


#: Most samples :func:`imu_trajectory` makes (a day at 100 Hz is 8.6e6): a larger duration·rate is a unit slip.
_MAX_SAMPLES = 1e8


def _count(value, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


# ---------------------------------------------------------------------------------------
# 1-D random walk
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RandomWalk1D:
    """A scalar random walk x_k = x_{k−1} + w_k observed as z_k = x_k + v_k.

    Attributes
    ----------
    x : numpy.ndarray, shape (n,)
        True states x_1 … x_n.
    z : numpy.ndarray, shape (n,)
        Measurements z_1 … z_n.
    x0 : float
        The known initial state x_0.
    q : float
        Process noise variance, Var(w_k) (units of x squared per step).
    r : float
        Measurement noise variance, Var(v_k).
    seed : int
    """

    x: np.ndarray
    z: np.ndarray
    x0: float
    q: float
    r: float
    seed: int

    def __len__(self) -> int:
        return len(self.x)


def random_walk_1d(n_steps: int, q: float, r: float, seed: int, x0: float = 0.0) -> RandomWalk1D:
    """Simulate a 1-D random walk and its noisy measurements.

    Parameters
    ----------
    n_steps : int
        Number of steps n.
    q : float
        Process noise variance per step (≥ 0).
    r : float
        Measurement noise variance (≥ 0).
    seed : int
        Seed; draws w (n,) then v (n,), each standard normal, scaled by √q and √r.
    x0 : float
        Initial state.

    Returns
    -------
    RandomWalk1D
    """
    n = _count(n_steps, "n_steps")
    q = as_scalar(q, "q", allow_zero=True)
    r = as_scalar(r, "r", allow_zero=True)
    x0 = as_real(x0, "x0")
    rng = np.random.default_rng(as_seed(seed))
    w = np.sqrt(q) * rng.standard_normal(n)
    v = np.sqrt(r) * rng.standard_normal(n)
    x = x0 + np.cumsum(w)
    return RandomWalk1D(x, x + v, x0, q, r, int(seed))


# ---------------------------------------------------------------------------------------
# Constant-velocity target
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CVTarget:
    """A constant-velocity target driven by white acceleration, observed in position.

    The state is x = [p, v] (positions of all axes, then velocities), length 2d. The
    acceleration is constant over each step and white between steps, so the exact discrete
    model is x_k = F x_{k−1} + G a_k, a_k ~ N(0, σ_a² I_d), with Q = σ_a² G Gᵀ, and
    z_k = H x_k + n_k, n_k ~ N(0, σ_z² I_d).

    Attributes
    ----------
    t : numpy.ndarray, shape (n,)
        Times t_k = k·dt, k = 1 … n, s.
    x : numpy.ndarray, shape (n, 2d)
        True states [p (m), v (m/s)].
    z : numpy.ndarray, shape (n, d)
        Position measurements, m.
    x0 : numpy.ndarray, shape (2d,)
        Initial state at t = 0.
    F : numpy.ndarray, shape (2d, 2d)
        [[I, dt I], [0, I]].
    G : numpy.ndarray, shape (2d, d)
        [[dt²/2 I], [dt I]].
    Q : numpy.ndarray, shape (2d, 2d)
        σ_a² G Gᵀ.
    H : numpy.ndarray, shape (d, 2d)
        [I, 0].
    R : numpy.ndarray, shape (d, d)
        σ_z² I.
    dt, sigma_a, sigma_meas : float
        Step (s), acceleration noise σ_a (m/s²), measurement noise σ_z (m).
    seed : int
    """

    t: np.ndarray
    x: np.ndarray
    z: np.ndarray
    x0: np.ndarray
    F: np.ndarray
    G: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray
    dt: float
    sigma_a: float
    sigma_meas: float
    seed: int

    def __len__(self) -> int:
        return len(self.t)


def cv_target(n_steps: int, dt: float, sigma_a: float, sigma_meas: float, seed: int, dim: int = 2,
              x0=None) -> CVTarget:
    """Simulate a constant-velocity target and its position measurements.

    Parameters
    ----------
    n_steps : int
        Number of steps n.
    dt : float
        Step, s.
    sigma_a : float
        Standard deviation of the acceleration per axis, m/s².
    sigma_meas : float
        Standard deviation of the position measurement per axis, m.
    seed : int
        Seed; draws the accelerations (n, d) then the measurement noise (n, d).
    dim : int
        Number of spatial axes d (1, 2 or 3).
    x0 : array_like, shape (2d,), optional
        Initial state [p, v]; default p = 0, v = 1 m/s on every axis.

    Returns
    -------
    CVTarget
    """
    n = _count(n_steps, "n_steps")
    dt = as_scalar(dt, "dt")
    sigma_a = as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_meas = as_scalar(sigma_meas, "sigma_meas", allow_zero=True)
    if isinstance(dim, (bool, np.bool_)) or not isinstance(dim, (int, np.integer)) or dim not in (1, 2, 3):
        raise ValueError(f"dim must be 1, 2 or 3 (an integer), got {dim!r}")
    d = int(dim)
    x0 = np.concatenate([np.zeros(d), np.ones(d)]) if x0 is None else as_vector(x0, "x0", 2 * d)
    I, Z = np.eye(d), np.zeros((d, d))
    F = np.block([[I, dt * I], [Z, I]])
    G = np.vstack([0.5 * dt * dt * I, dt * I])
    Q = sigma_a**2 * G @ G.T
    H = np.hstack([I, Z])
    R = sigma_meas**2 * I
    rng = np.random.default_rng(as_seed(seed))
    accel = sigma_a * rng.standard_normal((n, d))
    meas_noise = sigma_meas * rng.standard_normal((n, d))
    x = np.empty((n, 2 * d))
    state = x0.copy()
    for k in range(n):
        state = F @ state + G @ accel[k]
        x[k] = state
    z = x @ H.T + meas_noise
    t = dt * np.arange(1, n + 1)
    return CVTarget(t, x, z, x0.copy(), F, G, Q, H, R, dt, sigma_a, sigma_meas, int(seed))


# ---------------------------------------------------------------------------------------
# IMU trajectory
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ImuScenario:
    """A 3-D vehicle trajectory with exact truth and simulated IMU readings.

    The clean readings are the exact specific force and angular rate of a smooth analytic
    motion at the sample times; the truth is what the course's midpoint mechanisation
    (:func:`kalman_course.core.imu.dead_reckon`) makes of them from the true initial state, so
    integrating ``imu_clean`` reproduces the truth to round-off. (It differs from the
    analytic motion by the integration error, millimetres after a minute at 100 Hz.)

    The measured readings add, per sample k with step dt,
    ``f̃_k = f_k + b_a,k + n_a,k`` and ``ω̃_k = ω_k + b_ω,k + n_ω,k`` with
    n ~ N(0, (density/√dt)² I) and biases that follow random walks
    ``b_{k+1} = b_k + density_b √dt N(0, I)``.

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        Sample times, s.
    position : numpy.ndarray, shape (N, 3)
        True position, navigation frame (z up), m.
    velocity : numpy.ndarray, shape (N, 3)
        True velocity, m/s.
    rotation : numpy.ndarray, shape (N, 3, 3)
        True attitude R_nb.
    quaternion : numpy.ndarray, shape (N, 4)
        True attitude as (w, x, y, z), w ≥ 0.
    imu : ImuData
        Measured (noisy, biased) readings: specific force m/s², angular rate rad/s.
    imu_clean : ImuData
        Noise-free, bias-free readings.
    accel_bias : numpy.ndarray, shape (N, 3)
        True accelerometer bias b_a at each sample, m/s².
    gyro_bias : numpy.ndarray, shape (N, 3)
        True gyroscope bias b_ω at each sample, rad/s.
    gravity : numpy.ndarray, shape (3,)
        g_n, m/s².
    accel_noise_density : float
        Continuous white-noise density of the accelerometer, m/s²/√Hz.
    gyro_noise_density : float
        Continuous white-noise density of the gyroscope, rad/s/√Hz.
    accel_bias_density : float
        Density of the accelerometer bias random walk, m/s³/√Hz.
    gyro_bias_density : float
        Density of the gyroscope bias random walk, rad/s²/√Hz.
    seed : int
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    quaternion: np.ndarray
    imu: ImuData
    imu_clean: ImuData
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    gravity: np.ndarray
    accel_noise_density: float
    gyro_noise_density: float
    accel_bias_density: float
    gyro_bias_density: float
    seed: int

    def state(self, k: int) -> NavState:
        """The true state at sample ``k``."""
        return NavState(self.position[k].copy(), self.velocity[k].copy(), self.rotation[k].copy())

    def __len__(self) -> int:
        return len(self.t)


def _analytic_motion(t: np.ndarray, gravity: np.ndarray):
    """Closed-form motion: returns p0, v0, R (N,3,3), ω_b (N,3) and f_b (N,3)."""
    two_pi = 2.0 * np.pi
    # speed s(t) and its derivative (m/s, m/s²)
    speed = 8.0 + 3.0 * np.sin(two_pi * t / 20.0)
    dspeed = 3.0 * two_pi / 20.0 * np.cos(two_pi * t / 20.0)
    # yaw ψ(t) and rate (rad, rad/s)
    yaw_rate = 0.05 + 0.25 * np.sin(two_pi * t / 12.0)
    yaw = 0.05 * t - 0.25 * 12.0 / two_pi * (np.cos(two_pi * t / 12.0) - 1.0)
    # pitch θ and roll φ: small oscillations (rad, rad/s)
    pitch = 0.03 * np.sin(two_pi * t / 9.0)
    dpitch = 0.03 * two_pi / 9.0 * np.cos(two_pi * t / 9.0)
    roll = 0.04 * np.sin(two_pi * t / 7.0)
    droll = 0.04 * two_pi / 7.0 * np.cos(two_pi * t / 7.0)
    # height z(t) = sin(2π t/25) m
    w_z = two_pi / 25.0
    dz = w_z * np.cos(w_z * t)
    ddz = -w_z * w_z * np.sin(w_z * t)

    c, s = np.cos(yaw), np.sin(yaw)
    zero, one = np.zeros_like(t), np.ones_like(t)
    vel = np.stack([speed * c, speed * s, dz], axis=1)
    acc = np.stack([dspeed * c - speed * yaw_rate * s, dspeed * s + speed * yaw_rate * c, ddz], axis=1)

    def rot_x(a):
        ca, sa = np.cos(a), np.sin(a)
        return np.stack([np.stack([one, zero, zero], -1), np.stack([zero, ca, -sa], -1),
                         np.stack([zero, sa, ca], -1)], -2)

    def rot_y(a):
        ca, sa = np.cos(a), np.sin(a)
        return np.stack([np.stack([ca, zero, sa], -1), np.stack([zero, one, zero], -1),
                         np.stack([-sa, zero, ca], -1)], -2)

    def rot_z(a):
        ca, sa = np.cos(a), np.sin(a)
        return np.stack([np.stack([ca, -sa, zero], -1), np.stack([sa, ca, zero], -1),
                         np.stack([zero, zero, one], -1)], -2)

    Rx, Ry = rot_x(roll), rot_y(pitch)
    R = rot_z(yaw) @ Ry @ Rx
    ez = np.stack([zero, zero, yaw_rate], -1)
    ey = np.stack([zero, dpitch, zero], -1)
    ex = np.stack([droll, zero, zero], -1)
    RyRx = Ry @ Rx
    omega = (np.einsum("kji,kj->ki", RyRx, ez) + np.einsum("kji,kj->ki", Rx, ey) + ex)
    f = np.einsum("kji,kj->ki", R, acc - gravity)
    p0 = np.array([0.0, 0.0, np.sin(w_z * t[0])])
    return p0, vel[0], R, omega, f, vel, acc


def imu_trajectory(seed: int, duration: float = 60.0, rate: float = 100.0,
                   accel_noise_density: float = 0.01, gyro_noise_density: float = 1.75e-4,
                   accel_bias_density: float = 1.67e-4, gyro_bias_density: float = 2.91e-6,
                   accel_bias0=(0.0, 0.0, 0.0), gyro_bias0=(0.0, 0.0, 0.0),
                   gravity=(0.0, 0.0, -9.8092)) -> ImuScenario:
    """Simulate a vehicle-like trajectory and its IMU readings with exact ground truth.

    The motion (speed 5–11 m/s, yaw rate up to 0.3 rad/s, a few degrees of roll and
    pitch, ±1 m of height) is analytic; see :class:`ImuScenario` for how truth and
    readings relate. The default noise densities are those of the KITTI IMU metadata.

    Parameters
    ----------
    seed : int
        Seed; draws, in this order, accelerometer white noise (N, 3), gyroscope white
        noise (N, 3), accelerometer bias increments (N−1, 3), gyroscope bias increments
        (N−1, 3), all standard normal.
    duration : float
        Length, s.
    rate : float
        Sample rate, Hz; N = round(duration·rate) + 1 samples at t = k/rate.
    accel_noise_density, gyro_noise_density : float
        White-noise densities, m/s²/√Hz and rad/s/√Hz (per-sample σ = density·√rate).
    accel_bias_density, gyro_bias_density : float
        Bias random-walk densities, m/s³/√Hz and rad/s²/√Hz.
    accel_bias0, gyro_bias0 : array_like, shape (3,)
        Biases at t = 0, m/s² and rad/s.
    gravity : array_like, shape (3,)
        g_n, m/s².

    Returns
    -------
    ImuScenario
    """
    seed = as_seed(seed)
    duration = as_scalar(duration, "duration")
    rate = as_scalar(rate, "rate")
    nd_a = as_scalar(accel_noise_density, "accel_noise_density", allow_zero=True)
    nd_w = as_scalar(gyro_noise_density, "gyro_noise_density", allow_zero=True)
    bd_a = as_scalar(accel_bias_density, "accel_bias_density", allow_zero=True)
    bd_w = as_scalar(gyro_bias_density, "gyro_bias_density", allow_zero=True)
    b_a0 = as_vector(accel_bias0, "accel_bias0", 3)
    b_w0 = as_vector(gyro_bias0, "gyro_bias0", 3)
    g = as_vector(gravity, "gravity", 3)
    samples = duration * rate
    if not np.isfinite(samples) or samples > _MAX_SAMPLES:
        raise ValueError(f"duration·rate must give at most {_MAX_SAMPLES:.0e} samples, got duration={duration:g} s, "
                         f"rate={rate:g} Hz")
    n = int(round(samples)) + 1
    if n < 2:
        raise ValueError(f"duration·rate must give at least two samples, got duration={duration}, rate={rate}")
    t = np.arange(n) / rate
    dt = 1.0 / rate

    p0, v0, R_an, omega, f, _, _ = _analytic_motion(t, g)
    clean = ImuData(t, f, omega, np.zeros(n, dtype=bool))
    truth = dead_reckon(clean, NavState(p0, v0, R_an[0]), g)

    rng = np.random.default_rng(seed)
    n_a = nd_a / np.sqrt(dt) * rng.standard_normal((n, 3))
    n_w = nd_w / np.sqrt(dt) * rng.standard_normal((n, 3))
    steps_a = bd_a * np.sqrt(dt) * rng.standard_normal((n - 1, 3))
    steps_w = bd_w * np.sqrt(dt) * rng.standard_normal((n - 1, 3))
    b_a = b_a0 + np.vstack([np.zeros(3), np.cumsum(steps_a, axis=0)])
    b_w = b_w0 + np.vstack([np.zeros(3), np.cumsum(steps_w, axis=0)])
    measured = ImuData(t, f + b_a + n_a, omega + b_w + n_w, np.zeros(n, dtype=bool))
    return ImuScenario(t, truth.position, truth.velocity, truth.rotation, so3.matrix_to_quat(truth.rotation),
                       measured, clean, b_a, b_w, g, nd_a, nd_w, bd_a, bd_w, seed)
