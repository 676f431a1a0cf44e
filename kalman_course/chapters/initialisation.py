"""Initialisation without the truth (chapter 10): where does the first state come from?

Every run of chapter 08 starts from the true state, which hides the seed lecture's first
step, pose initialisation. Here the initial state is built from the sensors alone, in the
order a real system does it, and its uncertainty P̂₀ is derived from the sensors' errors:

1. **Standstill** (:func:`standstill_statistics`, :func:`detect_standstill`): windows of
   the IMU stream where the car is still: the mean specific force has the length of
   gravity, the mean rate is near zero and the readings are quiet (no road or engine
   vibration). The thresholds are datasheet-like numbers (mg, °/s).
2. **Levelling** (:func:`roll_pitch_from_force`, :func:`level`): at rest the accelerometer
   reads f = R_nbᵀ(0, 0, g), so roll and pitch follow from the mean of f. Yaw does not:
   a turn about the vertical leaves f unchanged. Nor can levelling tell a tilt from a
   horizontal acceleration a (or accelerometer bias): it reads a as a tilt of a/g.
3. **Heading, position, velocity from GNSS fixes** (:func:`heading_from_fixes`,
   :func:`speed_for_heading`, :func:`initialise_from_gnss`): once the car drives, the
   displacement between two fixes points along its path. With fixes of σ per axis a
   distance d apart the heading's σ is √2 σ / d, so a useful heading needs distance: at
   σ = 1 m and 3°, 27 m. The gyro carries the levelled attitude from the standstill to the
   fixes, so the chord's direction is compared with the body's mean direction over the
   chord, and the heading is only taken from a chord over which the gyro saw little turning.
   Position is the latest fix, velocity the chord divided by its duration with the IMU's
   acceleration correcting the half-chord lag.
4. **A pose from visual odometry** (:func:`initialise_from_pose`): VO reports poses in its
   own frame, anchored at its first pose. Aligned by that first pose, its first pose is
   whatever the alignment says (in this data: the ground truth of frame 0, so it is exact
   by construction and not a measurement). VO can give velocity and relative motion, not
   an absolute position or heading; those come from the alignment.
5. **P̂₀** (:func:`initial_covariance`): the σ's of steps 2–4, not guessed numbers; the
   biases keep the configuration's prior (nothing here observes them).

The experiments (:func:`compare_starts`, :func:`p0_scaling`) run the chapter-08 ESKF with
GNSS (and optionally lidar) from this initial state and from the truth, and with P̂₀ scaled
up and down, scoring position, tilt and heading errors and the 6-dof pose NEES against the
ground truth over time (:func:`run_errors`, :func:`settling_time`).

Real and simulated inputs: the IMU, the ground truth and the ORB-SLAM2 / S-PTAM poses are
real KITTI sequence 00 data; the GNSS fixes a filter sees are the OXTS positions plus
simulated white noise (σ = 1 m, seeded, ``ex.gnss.observations()``); lidar poses are
simulated (truth plus seeded noise).
"""

from __future__ import annotations

from collections.abc import Mapping

import math
from dataclasses import dataclass, field

import numpy as np

from kalman_course.chapters.consistency import _config
from kalman_course.core import so3
from kalman_course.core.linalg import symmetrise
from kalman_course.core.imu import NavState, dead_reckon
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.core.validation import (as_covariance, as_real_array, as_rotation, as_rows, as_scalar,
                                           as_vector, check_rotations)
from kalman_course.data import simulate_gnss
from kalman_course.evaluation import metrics
from kalman_course.evaluation.pose import POSE_INDEX
from kalman_course.filters import eskf

__all__ = [
    "MILLI_G", "roll_pitch_from_force", "rotation_from_euler", "euler_from_rotation",
    "StandstillStatistics", "standstill_statistics", "detect_standstill",
    "Levelling", "level", "tilt_sigma",
    "heading_from_fixes", "heading_sigma", "speed_for_heading", "lag_corrected_velocity",
    "initial_covariance", "Initialisation", "initialise_from_gnss", "initialise_from_pose",
    "RunErrors", "run_errors", "settling_time", "StartComparison", "compare_starts",
    "ERROR_BLOCKS", "scale_blocks", "p0_block_study",
    "P0Run", "p0_scaling",
]

#: One milli-g in m/s², with the standard gravity 9.80665 m/s² that datasheets use.
MILLI_G = 9.80665e-3

_DEG = math.pi / 180.0


# ---------------------------------------------------------------------------------------
# Angles
# ---------------------------------------------------------------------------------------

def roll_pitch_from_force(specific_force) -> tuple[float, float]:
    """Roll and pitch from a specific force measured at rest.

    At rest f = R_nbᵀ (0, 0, g) with R_nb = R_z(ψ) R_y(θ) R_x(φ), that is
    f = g (−sin θ, cos θ sin φ, cos θ cos φ), so

        φ = atan2(f_y, f_z),    θ = atan2(−f_x, √(f_y² + f_z²)),

    whatever the yaw ψ and whatever the length of f.

    Parameters
    ----------
    specific_force : array_like, shape (3,) or (n, 3)
        One reading, or readings whose mean is used, body frame (x forward, y left, z up),
        m/s².

    Returns
    -------
    roll, pitch : float
        φ and θ, rad.

    Raises
    ------
    ValueError
        If the argument is not (3,) or (n, 3) finite numbers, or its mean has no vertical
        direction (a zero vector).
    """
    arr = as_real_array(specific_force, "specific_force")
    f = as_rows(arr[None] if arr.ndim == 1 else arr, "specific_force", (3,)).mean(axis=0)
    if not np.linalg.norm(f) > 0.0:
        raise ValueError("specific_force must not average to zero: levelling needs gravity in the reading")
    fx, fy, fz = f
    return float(math.atan2(fy, fz)), float(math.atan2(-fx, math.hypot(fy, fz)))


def rotation_from_euler(roll, pitch, yaw) -> np.ndarray:
    """R_nb = R_z(ψ) R_y(θ) R_x(φ) from roll φ, pitch θ and yaw ψ (rad); shape (3, 3)."""
    angles = [as_vector([v], name, 1)[0] for v, name in ((roll, "roll"), (pitch, "pitch"), (yaw, "yaw"))]
    phi, theta, psi = angles
    return so3.exp(np.array([0.0, 0.0, psi])) @ so3.exp(np.array([0.0, theta, 0.0])) @ so3.exp(
        np.array([phi, 0.0, 0.0]))


def euler_from_rotation(R) -> np.ndarray:
    """(roll, pitch, yaw) in rad of R_nb = R_z(ψ) R_y(θ) R_x(φ); R (3, 3) or (n, 3, 3).

    Returns an array of shape (3,) or (n, 3): φ = atan2(R₂₁, R₂₂), θ = −asin(R₂₀),
    ψ = atan2(R₁₀, R₀₀).
    """
    R = as_real_array(R, "R")
    if R.shape[-2:] != (3, 3) or R.ndim not in (2, 3) or not np.isfinite(R).all():
        raise ValueError(f"R must be a finite rotation matrix (3, 3) or a stack (n, 3, 3), got shape {R.shape}")
    check_rotations(R, "R")
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def _yaw_rotation(psi: float) -> np.ndarray:
    return so3.exp(np.array([0.0, 0.0, psi]))


# ---------------------------------------------------------------------------------------
# Standstill
# ---------------------------------------------------------------------------------------

def _imu_arrays(imu):
    """t (N,), f (N, 3), ω (N, 3), interpolated flags (N,) of an IMU record, validated."""
    for name in ("t", "specific_force", "angular_rate"):
        if not hasattr(imu, name):
            raise ValueError(f"imu must have t (N,), specific_force (N, 3) and angular_rate (N, 3); "
                             f"missing {name!r}")
    t = as_rows(imu.t, "imu.t")
    f = as_rows(imu.specific_force, "imu.specific_force", (3,), len(t))
    w = as_rows(imu.angular_rate, "imu.angular_rate", (3,), len(t))
    if len(t) < 2 or (np.diff(t) <= 0.0).any():
        raise ValueError("imu.t must hold at least two strictly increasing times")
    flags = np.asarray(getattr(imu, "interpolated", np.zeros(len(t), dtype=bool)), dtype=bool)
    if flags.shape != t.shape:
        raise ValueError(f"imu.interpolated must have shape ({len(t)},), got {flags.shape}")
    return t, f, w, flags


def _gravity_norm(gravity) -> float:
    g = float(np.linalg.norm(as_vector(gravity, "gravity", 3)))
    if g <= 0.0:
        raise ValueError("gravity must be a non-zero vector (m/s², navigation frame)")
    return g


def _window_sums(x: np.ndarray, n: int) -> np.ndarray:
    """Sums of ``x`` over every run of ``n`` consecutive rows: shape (len(x) − n + 1, ...)."""
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])
    return c[n:] - c[:-n]


@dataclass(frozen=True)
class StandstillStatistics:
    """The detector's three numbers for every window of ``n`` consecutive IMU samples.

    Window j holds samples j … j + n − 1.

    Attributes
    ----------
    t_start, t_end : numpy.ndarray, shape (M,)
        Times of a window's first and last sample, s.
    gravity_deviation : numpy.ndarray, shape (M,)
        | |f̄| − g |, the mean specific force's length minus gravity's, m/s².
    mean_rate : numpy.ndarray, shape (M,)
        |ω̄|, the length of the mean angular rate, rad/s.
    vibration : numpy.ndarray, shape (M,)
        √(mean |f_k+1 − f_k|² / 6): the per-axis, per-sample standard deviation of a white
        noise that would make the readings this jittery, m/s².
    interpolated : numpy.ndarray of bool, shape (M,)
        True where the window holds an interpolated (made-up) sample.
    n : int
        Samples per window.
    """

    t_start: np.ndarray
    t_end: np.ndarray
    gravity_deviation: np.ndarray
    mean_rate: np.ndarray
    vibration: np.ndarray
    interpolated: np.ndarray
    n: int


def standstill_statistics(imu, gravity, window: float = 0.5) -> StandstillStatistics:
    """Per-window statistics of the IMU stream that tell a standing car from a moving one.

    Parameters
    ----------
    imu : object
        ``t`` (N,) s, ``specific_force`` (N, 3) m/s², ``angular_rate`` (N, 3) rad/s and
        optionally ``interpolated`` (N,) bool (for example ``load_kitti("stop_go").imu``:
        real KITTI data).
    gravity : array_like, shape (3,)
        g_n, m/s²; only its length g is used.
    window : float
        Window length, s; converted to n = round(window / median step) samples (at least 2).

    Returns
    -------
    StandstillStatistics
    """
    t, f, w, flags = _imu_arrays(imu)
    g = _gravity_norm(gravity)
    window = as_scalar(window, "window")
    n = max(2, int(round(window / float(np.median(np.diff(t))))))
    if n > len(t):
        raise ValueError(f"window = {window:g} s needs {n} samples, the IMU record has {len(t)}")
    f_mean = _window_sums(f, n) / n
    w_mean = _window_sums(w, n) / n
    jump2 = np.sum(np.diff(f, axis=0) ** 2, axis=1)                 # |f_k+1 − f_k|², (N − 1,)
    vibration = np.sqrt(_window_sums(jump2, n - 1) / (n - 1) / 6.0)  # E|Δf|² = 6σ² for white noise
    return StandstillStatistics(t[: len(t) - n + 1].copy(), t[n - 1:].copy(),
                                np.abs(np.linalg.norm(f_mean, axis=1) - g), np.linalg.norm(w_mean, axis=1),
                                vibration, _window_sums(flags.astype(float), n) > 0.0, n)


def detect_standstill(imu, gravity, *, window: float = 0.5, gravity_tolerance_mg: float = 2.0,
                      rate_max_dps: float = 0.5, vibration_max_mg: float = 2.0,
                      min_duration: float = 1.0) -> np.ndarray:
    """Spans of the IMU stream where the car stands still, found without the truth.

    A window of ``window`` seconds counts as still when all three hold:

    - | |f̄| − g | ≤ ``gravity_tolerance_mg`` (default 2 mg ≈ 0.020 m/s²): no net acceleration
      along gravity. Only weakly along the horizontal: a horizontal acceleration a changes
      |f̄| by √(g² + a²) − g ≈ a²/2g, so 2 mg lets up to 0.62 m/s² through (see :func:`tilt_sigma`);
    - |ω̄| ≤ ``rate_max_dps`` (default 0.5 °/s): not turning. A MEMS gyro bias of tens of °/h
      and the Earth's rate (15 °/h) are far below it;
    - vibration ≤ ``vibration_max_mg`` (default 2 mg per sample per axis, a white noise of
      0.2 mg/√Hz at 100 Hz): quiet, no engine or road vibration. This is what separates a
      stop from steady straight driving, which the other two cannot.

    The still samples are the union of the still windows; runs of them at least
    ``min_duration`` long are returned. Windows holding an interpolated sample never count.

    What it cannot see: a car moving at constant velocity on a perfectly smooth road, or
    creeping with a small constant acceleration, reads like a stopped one. On KITTI's only
    stop (tau 56.3–57.5 s) it returns 56.46–57.86 s, including about 0.4 s of creeping
    off at up to 0.38 m/s (see :func:`level` for what that costs).

    Parameters
    ----------
    imu : object
        As for :func:`standstill_statistics` (real KITTI IMU, or a synthetic one).
    gravity : array_like, shape (3,)
        g_n, m/s².
    window : float
        Window length, s.
    gravity_tolerance_mg, rate_max_dps, vibration_max_mg : float
        The thresholds, in mg (1 mg = 9.80665e-3 m/s²) and degrees per second.
    min_duration : float
        Shortest span returned, s (from its first to its last sample).

    Returns
    -------
    numpy.ndarray, shape (K, 2)
        (time of the first, time of the last still sample) of each span, s, in order;
        K = 0 when the car never stood still.
    """
    tolerance = as_scalar(gravity_tolerance_mg, "gravity_tolerance_mg") * MILLI_G
    rate_max = as_scalar(rate_max_dps, "rate_max_dps") * _DEG
    vibration_max = as_scalar(vibration_max_mg, "vibration_max_mg") * MILLI_G
    min_duration = as_scalar(min_duration, "min_duration", allow_zero=True)
    stats = standstill_statistics(imu, gravity, window)
    still_window = ((stats.gravity_deviation <= tolerance) & (stats.mean_rate <= rate_max)
                    & (stats.vibration <= vibration_max) & ~stats.interpolated)
    t = np.asarray(imu.t, dtype=float)
    cover = np.zeros(len(t) + 1)                 # +1 where a still window starts, −1 after it ends
    starts = np.flatnonzero(still_window)
    np.add.at(cover, starts, 1.0)
    np.add.at(cover, starts + stats.n, -1.0)
    still = np.cumsum(cover[:-1]) > 0.0
    edges = np.flatnonzero(np.diff(np.concatenate([[0], still.astype(np.int8), [0]])))
    first, last = edges[0::2], edges[1::2] - 1
    spans = np.column_stack([t[first], t[last]]) if first.size else np.empty((0, 2))
    return spans[spans[:, 1] - spans[:, 0] >= min_duration]


# ---------------------------------------------------------------------------------------
# Levelling
# ---------------------------------------------------------------------------------------

def tilt_sigma(gravity_tolerance, gravity_norm, accel_bias_sigma=0.0) -> float:
    """σ of roll and pitch from levelling on a window the detector called still, rad.

    Levelling reads a horizontal acceleration a as a tilt a/g. The detector's bound
    | |f̄| − g | ≤ δ admits a constant horizontal acceleration up to
    a_max = √((g + δ)² − g²) ≈ √(2gδ); an accelerometer bias b_a acts the same way. Taking
    a_max as one σ (wide on purpose) and adding the bias's σ:

        σ_tilt = √(a_max² + σ_ba²) / g.

    Parameters
    ----------
    gravity_tolerance : float
        δ, m/s² (for example 2 mg = 0.0196 m/s²).
    gravity_norm : float
        g, m/s².
    accel_bias_sigma : float
        σ_ba per axis, m/s².
    """
    delta = as_scalar(gravity_tolerance, "gravity_tolerance", allow_zero=True)
    g = as_scalar(gravity_norm, "gravity_norm")
    sigma_ba = as_scalar(accel_bias_sigma, "accel_bias_sigma", allow_zero=True)
    a_max = math.sqrt((g + delta) ** 2 - g ** 2)
    return math.sqrt(a_max ** 2 + sigma_ba ** 2) / g


@dataclass(frozen=True)
class Levelling:
    """Roll and pitch from the accelerometer over a standstill.

    Attributes
    ----------
    span : numpy.ndarray, shape (2,)
        (first, last) sample time of the standstill used, s.
    n_samples : int
        Number of IMU samples averaged.
    mean_force : numpy.ndarray, shape (3,)
        f̄, body frame, m/s².
    gravity_measured : float
        |f̄|, m/s² (compare with the navigation frame's g).
    roll, pitch : float
        φ and θ, rad.
    rotation : numpy.ndarray, shape (3, 3)
        R_z(yaw) R_y(θ) R_x(φ) with the yaw asked for (default 0): levelling gives no yaw.
    sigma : float
        σ of roll and of pitch, rad (:func:`tilt_sigma`).
    """

    span: np.ndarray
    n_samples: int
    mean_force: np.ndarray
    gravity_measured: float
    roll: float
    pitch: float
    rotation: np.ndarray
    sigma: float


def level(imu, span, gravity, *, yaw: float = 0.0, gravity_tolerance_mg: float = 2.0,
          accel_bias_sigma: float = 0.02) -> Levelling:
    """Level the IMU: roll and pitch from its mean specific force over a standstill.

    The mean over the span, f̄, gives φ and θ (:func:`roll_pitch_from_force`). Any yaw can
    be put in (``yaw``): gravity says nothing about it. A horizontal acceleration during
    the span (a car creeping) or a horizontal accelerometer bias tilts the answer by a/g;
    on KITTI's stop the detector's span includes 0.4 s of creeping off and pitch comes out
    1.6° low (the truth's mean forward acceleration over the span, 0.27 m/s², predicts
    1.58°) while roll is within 0.01° (measured against the truth in
    ``tests/test_initialisation.py``).

    Parameters
    ----------
    imu : object
        ``t`` (N,) s and ``specific_force`` (N, 3) m/s² (e.g. ``load_kitti("stop_go").imu``).
    span : array_like, shape (2,)
        (start, end) of the standstill, s (a row of :func:`detect_standstill`).
    gravity : array_like, shape (3,)
        g_n, m/s².
    yaw : float
        ψ to put in the returned rotation, rad.
    gravity_tolerance_mg : float
        The detector's tolerance, for the σ (:func:`tilt_sigma`).
    accel_bias_sigma : float
        σ_ba per axis, m/s², for the σ.

    Returns
    -------
    Levelling
    """
    t, f, _, _ = _imu_arrays(imu)
    span = as_vector(span, "span", 2)
    if not span[0] <= span[1]:
        raise ValueError(f"span must be (start, end) with start <= end, got {span}")
    inside = (t >= span[0]) & (t <= span[1])
    if inside.sum() < 2:
        raise ValueError(f"span [{span[0]:.3f}, {span[1]:.3f}] s holds fewer than two IMU samples")
    f_mean = f[inside].mean(axis=0)
    roll, pitch = roll_pitch_from_force(f_mean)
    g = _gravity_norm(gravity)
    sigma = tilt_sigma(as_scalar(gravity_tolerance_mg, "gravity_tolerance_mg", allow_zero=True) * MILLI_G, g,
                       accel_bias_sigma)
    return Levelling(span.copy(), int(inside.sum()), f_mean, float(np.linalg.norm(f_mean)), roll, pitch,
                     rotation_from_euler(roll, pitch, yaw), sigma)


# ---------------------------------------------------------------------------------------
# Heading, speed and velocity from fixes
# ---------------------------------------------------------------------------------------

def heading_sigma(sigma, distance, turn: float = 0.0) -> float:
    """σ of a heading taken from the chord between two fixes, rad.

    Each fix has independent errors of σ per axis, so the chord's error across its own
    direction has σ√2 and turns the chord by √2 σ / d (small angles). A heading change
    ``turn`` over the chord, seen by the gyro but not by the fixes, leaves an error of up
    to half of it, which as a uniform error has σ = turn / (2√3):

        σ_ψ = √(2σ²/d² + turn²/12).
    """
    sigma = as_scalar(sigma, "sigma", allow_zero=True)
    distance = as_scalar(distance, "distance")
    turn = as_scalar(turn, "turn", allow_zero=True)
    return math.sqrt(2.0 * sigma ** 2 / distance ** 2 + turn ** 2 / 12.0)


def heading_from_fixes(p_a, p_b, sigma) -> tuple[float, float, float]:
    """Heading of the horizontal chord from fix ``p_a`` to fix ``p_b``.

    Parameters
    ----------
    p_a, p_b : array_like, shape (3,) or (2,)
        Two fixes, navigation frame (x, y[, z]), m.
    sigma : float
        σ per axis of each fix, m.

    Returns
    -------
    heading : float
        ψ = atan2(Δy, Δx), rad: the yaw of a body whose x axis points along the chord.
    sigma_heading : float
        √2 σ / d, rad (:func:`heading_sigma` with no turn).
    distance : float
        d, the horizontal length of the chord, m.

    Raises
    ------
    ValueError
        If the fixes coincide horizontally (no direction).
    """
    a = as_vector(p_a, "p_a")
    b = as_vector(p_b, "p_b")
    if a.shape != b.shape or a.shape[0] not in (2, 3):
        raise ValueError(f"p_a and p_b must both have shape (2,) or (3,), got {a.shape} and {b.shape}")
    dx, dy = b[0] - a[0], b[1] - a[1]
    d = math.hypot(dx, dy)
    if d == 0.0:
        raise ValueError("p_a and p_b coincide horizontally: a chord of length 0 has no heading")
    return math.atan2(dy, dx), heading_sigma(sigma, d), d


def speed_for_heading(sigma, heading_sigma_max, interval) -> float:
    """The speed at which two fixes ``interval`` seconds apart give a heading σ of ``heading_sigma_max``.

    From σ_ψ = √2 σ / d with d = v · interval: v = √2 σ / (σ_ψ · interval), m/s. With 1 Hz
    fixes of σ = 1 m and a 3° target: 27 m/s from consecutive fixes, 9 m/s over 3 s.
    """
    sigma = as_scalar(sigma, "sigma", allow_zero=True)
    target = as_scalar(heading_sigma_max, "heading_sigma_max")
    interval = as_scalar(interval, "interval")
    return math.sqrt(2.0) * sigma / (target * interval)


def lag_corrected_velocity(p_a, p_b, t_a, t_b, t, acceleration) -> np.ndarray:
    """Velocity at t_b from two positions and the acceleration between them.

    The chord (p_b − p_a)/T, T = t_b − t_a, is the mean velocity over the interval; the
    velocity at its end differs by the acceleration's weighted integral. From
    p_b − p_a = ∫ v dt and v(s) = v_b − ∫_s^{t_b} a:

        v_b = (p_b − p_a)/T + (1/T) ∫_{t_a}^{t_b} (s − t_a) a(s) ds

    (the integral by the trapezoid rule over the samples).

    Parameters
    ----------
    p_a, p_b : array_like, shape (3,)
        Positions at t_a and t_b, m.
    t_a, t_b : float
        Their times, s, t_a < t_b.
    t : array_like, shape (n,)
        Sample times of the acceleration inside [t_a, t_b], increasing, n ≥ 2.
    acceleration : array_like, shape (n, 3)
        The navigation-frame acceleration a = R f + g at those times, m/s².

    Returns
    -------
    numpy.ndarray, shape (3,)
        v_b, m/s.
    """
    p_a, p_b = as_vector(p_a, "p_a", 3), as_vector(p_b, "p_b", 3)
    t_a, t_b = float(as_vector([t_a], "t_a", 1)[0]), float(as_vector([t_b], "t_b", 1)[0])
    if not t_a < t_b:
        raise ValueError(f"t_a must be earlier than t_b, got t_a = {t_a} s, t_b = {t_b} s")
    s = as_rows(t, "t")
    a = as_rows(acceleration, "acceleration", (3,), len(s))
    if len(s) < 2 or (np.diff(s) <= 0.0).any() or s[0] < t_a - 1e-9 or s[-1] > t_b + 1e-9:
        raise ValueError("t must hold at least two increasing times inside [t_a, t_b]")
    T = t_b - t_a
    weighted = (s - t_a)[:, None] * a
    integral = np.sum(0.5 * (weighted[1:] + weighted[:-1]) * np.diff(s)[:, None], axis=0)
    return (p_b - p_a) / T + integral / T


# ---------------------------------------------------------------------------------------
# P̂₀ and the initial state
# ---------------------------------------------------------------------------------------

def initial_covariance(rotation, sigma_position, sigma_velocity, sigma_tilt, sigma_heading,
                       config="kitti_gnss") -> np.ndarray:
    """P̂₀ (15, 15) of δx = [δp, δv, δθ, δb_a, δb_ω] from the initialisation's σ's.

    Position and velocity are diagonal with the σ's given (per axis). The attitude's
    errors are known in the navigation frame, tilt about the horizontal axes and heading
    about the vertical: Σ_n = diag(σ_tilt², σ_tilt², σ_ψ²). The ESKF's δθ is in the body
    frame: Ř = R Exp(δθ) = Exp(R δθ) R, so the navigation-frame error is δθ_n = R δθ and
    Σ_θ = Rᵀ Σ_n R. The biases
    keep the configuration's prior σ's: nothing in the initialisation observes them.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        The initial attitude R_nb.
    sigma_position, sigma_velocity : float or array_like, shape (3,)
        σ per axis, m and m/s.
    sigma_tilt, sigma_heading : float
        σ of roll/pitch and of heading, rad.
    config : EskfConfig or str
        Where the bias σ's come from.
    """
    R = as_rotation(rotation, "rotation")
    sp = _sigma3(sigma_position, "sigma_position")
    sv = _sigma3(sigma_velocity, "sigma_velocity")
    st = as_scalar(sigma_tilt, "sigma_tilt", allow_zero=True)
    sh = as_scalar(sigma_heading, "sigma_heading", allow_zero=True)
    cfg = _config(config)
    P = np.zeros((15, 15))
    P[eskf.IDX_P, eskf.IDX_P] = np.diag(sp ** 2)
    P[eskf.IDX_V, eskf.IDX_V] = np.diag(sv ** 2)
    P[eskf.IDX_TH, eskf.IDX_TH] = R.T @ np.diag([st ** 2, st ** 2, sh ** 2]) @ R
    prior = cfg.prior_std
    P[eskf.IDX_BA, eskf.IDX_BA] = np.diag(prior[eskf.IDX_BA] ** 2)
    P[eskf.IDX_BW, eskf.IDX_BW] = np.diag(prior[eskf.IDX_BW] ** 2)
    return symmetrise(P)


def _sigma3(value, name: str) -> np.ndarray:
    """A σ per axis (3,) from a scalar or a (3,) array, checked to be finite and >= 0."""
    s = as_vector(np.full(3, value) if np.ndim(value) == 0 else value, name, 3)
    if (s < 0.0).any():
        raise ValueError(f"{name} must hold standard deviations (>= 0), got {s}")
    return s


@dataclass(frozen=True)
class Initialisation:
    """An initial state found without the truth, with the P̂₀ derived for it.

    Attributes
    ----------
    method : str
        How it was found (e.g. "levelling + GNSS chord").
    k0 : int
        Index of the IMU sample the filter starts at (``eskf.run(..., start=k0)``).
    t0 : float
        ``imu.t[k0]``, s.
    state : eskf.NominalState
        The initial nominal state (biases zero).
    P0 : numpy.ndarray, shape (15, 15)
        Its covariance.
    sigma : dict
        The σ's P̂₀ is built from: ``position`` (3,) m, ``velocity`` (3,) m/s, ``tilt`` and
        ``heading`` rad.
    levelling : Levelling or None
        The levelling used for roll and pitch.
    chord : tuple of float or None
        (t_a, t_b) of the two fixes (or poses) heading and velocity came from, s.
    distance : float
        Horizontal length of that chord, m.
    turn : float
        Heading change over the chord measured by the gyro, rad.
    """

    method: str
    k0: int
    t0: float
    state: eskf.NominalState
    P0: np.ndarray
    sigma: dict
    levelling: Levelling | None = None
    chord: tuple | None = None
    distance: float = float("nan")
    turn: float = float("nan")

    def describe(self) -> str:
        """The initial σ's and where they come from, as a Markdown table."""
        s = self.sigma
        rows = [f"Initialisation ({self.method}) at t0 = {self.t0:.2f} s", "",
                "| quantity | σ | from |", "|---|---|---|",
                f"| position | {np.max(s['position']):.2f} m | the latest fix's σ |",
                f"| velocity | {np.max(s['velocity']):.2f} m/s | chord over its duration (+ tilt × g × T/2) |",
                f"| roll, pitch | {np.rad2deg(s['tilt']):.2f}° | levelling: the acceleration the detector admits |",
                f"| heading | {np.rad2deg(s['heading']):.2f}° | √2σ/d over the chord, + turn/√12 |", "",
                "Inputs: the IMU as given (on KITTI: real); the fixes or poses as given (on KITTI: "
                "real OXTS positions plus simulated noise, or real ORB-SLAM2 poses)."]
        return "\n".join(rows)


def _fixes(fixes) -> PositionObservations:
    if isinstance(fixes, PositionObservations):
        return fixes
    if not (hasattr(fixes, "t") and hasattr(fixes, "position")):
        raise ValueError("fixes must be a PositionObservations (e.g. ex.gnss.observations()) or have t (M,) and "
                         f"position (M, 3); got {type(fixes).__name__}")
    return PositionObservations(fixes.t, fixes.position)


@dataclass(frozen=True)
class _Stream:
    """The minimal IMU record :func:`dead_reckon` reads."""

    t: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray


def _relative_attitude(t, f, w, k_start: int, R_start, gravity, k_stop: int | None = None):
    """Attitudes (n, 3, 3) of samples k_start … k_stop − 1 (default: to the end), carried by
    the gyro from R_start at k_start (biases zero)."""
    sl = slice(k_start, k_stop)
    imu = _Stream(t[sl], f[sl], w[sl])
    traj = dead_reckon(imu, NavState(np.zeros(3), np.zeros(3), R_start), gravity)
    return traj.rotation


def _mean_heading(R: np.ndarray) -> float:
    """Heading of the mean horizontal direction of the body x axes of R (n, 3, 3), rad."""
    u = R[:, 0:2, 0].mean(axis=0)
    return math.atan2(u[1], u[0])


def initialise_from_gnss(imu, fixes, gravity, standstill, *, sigma=None, config="kitti_gnss",
                         heading_sigma_max_deg: float = 3.0, max_turn_deg: float = 5.0,
                         max_chord_s: float = 10.0, gravity_tolerance_mg: float = 2.0) -> Initialisation:
    """Initial state from levelling at a standstill and the GNSS fixes after it.

    1. Level over ``standstill`` (:func:`level`): roll, pitch and their σ.
    2. From the standstill's last sample on, carry that attitude with the gyro (yaw 0 at
       the start): R_rel(t). The true attitude is R_z(ψ₀) R_rel(t) for one unknown ψ₀.
    3. For each fix b after the standstill, take the earliest fix a such that the gyro's
       heading changes by at most ``max_turn_deg`` over [t_a, t_b]; the chord a → b has
       direction ψ_chord and length d. With the car moving along its body x axis (no side
       slip: 0.05° mean, 1.8° spread on KITTI above 3 m/s), the chord points along the mean
       body direction over the interval, so ψ₀ = ψ_chord − ψ̄_rel. Accept the first b whose
       σ_ψ = √(2σ²/d² + turn²/12) is at most ``heading_sigma_max_deg``.
    4. State at the first IMU sample at or after t_b: position the fix z_b (σ per axis the
       fixes' σ), velocity :func:`lag_corrected_velocity` over the chord with the IMU's
       acceleration (σ √2σ/T per axis, plus g σ_tilt T/2 horizontally for the tilt's
       effect on that acceleration), attitude R_z(ψ₀) R_rel, biases zero.

    The fixes are what a receiver reports (for KITTI: ``ex.gnss.observations()``, the real
    OXTS positions plus simulated noise of σ = 1 m). The filter should then start at
    ``k0`` with :attr:`Initialisation.P0`; fixes up to t_b are ignored by ``eskf.run``
    because they are not after the start, so none is used twice.

    Parameters
    ----------
    imu : object
        ``t``, ``specific_force``, ``angular_rate`` (real KITTI IMU, e.g. ``ex.imu``).
    fixes : PositionObservations
        GNSS fixes: ``t`` (M,) s, ``position`` (M, 3) m.
    gravity : array_like, shape (3,)
        g_n, m/s².
    standstill : array_like, shape (2,)
        (start, end) of a standstill, s (from :func:`detect_standstill`).
    sigma : float, optional
        The fixes' σ per axis, m (default: the configuration's GNSS σ).
    config : EskfConfig or str
        Source of the GNSS σ (if ``sigma`` is None) and of the bias σ's.
    heading_sigma_max_deg : float
        Accept the heading once its σ is at most this, degrees.
    max_turn_deg : float
        Largest heading change over a chord, by the gyro, degrees.
    max_chord_s : float
        Longest chord, s (the lag correction of the velocity integrates the IMU over it).
    gravity_tolerance_mg : float
        The standstill detector's gravity tolerance, for the tilt σ.

    Returns
    -------
    Initialisation

    Raises
    ------
    ValueError
        For bad arguments, or when no chord after the standstill is long and straight
        enough for the heading σ asked for (the message says the best σ reached).
    """
    cfg = _config(config)
    t, f, w, _ = _imu_arrays(imu)
    obs = _fixes(fixes)
    g_vec = as_vector(gravity, "gravity", 3)
    sigma = cfg.gnss_std if sigma is None else as_scalar(sigma, "sigma")
    target = as_scalar(heading_sigma_max_deg, "heading_sigma_max_deg") * _DEG
    max_turn = as_scalar(max_turn_deg, "max_turn_deg", allow_zero=True) * _DEG
    max_chord = as_scalar(max_chord_s, "max_chord_s")
    lev = level(imu, standstill, g_vec, gravity_tolerance_mg=gravity_tolerance_mg,
                accel_bias_sigma=cfg.si("prior.accel_bias"))

    k_s = int(np.searchsorted(t, lev.span[1], side="right")) - 1
    R_rel = _relative_attitude(t, f, w, k_s, lev.rotation, g_vec)
    t_rel = t[k_s:]
    yaw_rel = np.unwrap(np.arctan2(R_rel[:, 1, 0], R_rel[:, 0, 0]))

    usable = np.flatnonzero((obs.t >= t_rel[0]) & (obs.t <= t_rel[-1]))
    best = math.inf
    for b in usable:
        for a in usable[(usable < b) & (obs.t[usable] >= obs.t[b] - max_chord)]:
            inside = (t_rel >= obs.t[a]) & (t_rel <= obs.t[b])
            if inside.sum() < 2:
                continue
            turn = float(np.ptp(yaw_rel[inside]))
            if turn > max_turn:
                continue                        # a later a gives a straighter chord
            psi_chord, _, d = heading_from_fixes(obs.position[a], obs.position[b], sigma)
            sig_psi = heading_sigma(sigma, d, turn)
            best = min(best, sig_psi)
            if sig_psi <= target:
                return _gnss_state(t, f, g_vec, obs, int(a), int(b), k_s, R_rel, inside, psi_chord, sig_psi,
                                   sigma, d, turn, lev, cfg)
            break                               # the earliest straight chord ending at b is the longest
    raise ValueError(f"no chord of GNSS fixes after the standstill ending at {lev.span[1]:.2f} s gives a heading "
                     f"σ ≤ {np.rad2deg(target):.2f}° over a turn ≤ {np.rad2deg(max_turn):.1f}° "
                     f"(best: {np.rad2deg(best):.2f}°); the car must drive far enough straight")


def _gnss_state(t, f, g_vec, obs, a, b, k_s, R_rel, inside, psi_chord, sig_psi, sigma, d, turn, lev, cfg):
    """The state and P̂₀ of :func:`initialise_from_gnss` once the chord a → b is chosen."""
    psi0 = psi_chord - _mean_heading(R_rel[inside])
    Rz = _yaw_rotation(psi0)
    t_a, t_b = float(obs.t[a]), float(obs.t[b])
    k_in = k_s + np.flatnonzero(inside)
    acc = np.einsum("ij,njk,nk->ni", Rz, R_rel[inside], f[k_in]) + g_vec       # a = R f + g
    v_b = lag_corrected_velocity(obs.position[a], obs.position[b], t_a, t_b, t[k_in], acc)
    k0 = int(np.searchsorted(t, t_b, side="left"))
    if k0 >= len(t) - 1:
        raise ValueError(f"the chord ends at {t_b:.2f} s, too close to the end of the IMU record")
    R0 = Rz @ R_rel[k0 - k_s]
    p0 = obs.position[b] + v_b * (t[k0] - t_b)
    T = t_b - t_a
    g = float(np.linalg.norm(g_vec))
    sv_noise = math.sqrt(2.0) * sigma / T
    sv_h = math.hypot(sv_noise, g * lev.sigma * T / 2.0)
    sig = {"position": np.full(3, sigma), "velocity": np.array([sv_h, sv_h, sv_noise]),
           "tilt": lev.sigma, "heading": sig_psi}
    P0 = initial_covariance(R0, sig["position"], sig["velocity"], lev.sigma, sig_psi, cfg)
    state = eskf.NominalState(p0, v_b.copy(), R0)
    return Initialisation("levelling + GNSS chord", k0, float(t[k0]), state, P0, sig, lev, (t_a, t_b), d, turn)


def initialise_from_pose(imu, poses, gravity, *, sigma_position, sigma_attitude_deg, k: int | None = None,
                         config="kitti_gnss") -> Initialisation:
    """Initial state from pose k of a pose source (visual odometry) and the pose before it.

    Position and attitude are pose k's; velocity is :func:`lag_corrected_velocity` over
    poses k − 1 → k, with the IMU's acceleration carried by the gyro from pose k − 1's
    attitude; biases zero.

    What a VO pose is worth: VO measures motion relative to its own first frame. Aligned
    by its first pose (as ``load_kitti("seq00").orb_slam2`` is: its camera frame 0 was
    mapped into the navigation frame with the ground truth's frame-0 pose), its pose at
    frame 0 equals the truth exactly — by construction, not by measurement — and its roll
    and pitch are the truth's, which VO alone cannot know (levelling must supply them).
    Later poses carry VO's drift. So a VO start inherits whatever fixed the VO frame;
    without GNSS or a map, position and heading are defined, not estimated.
    ``sigma_position`` and ``sigma_attitude_deg`` are therefore the caller's statement of
    how well that alignment is known, and the velocity's σ follows from the first as
    √2 σ_p / Δt. On sequence 00 the IMU starts 1.4 s after frame 0; by then ORB-SLAM2,
    whose first steps are about 23 % short (6.4 m/s against the true 8.3 m/s), is already
    1.35 m and 1.5° off the truth, and that is the start it gives.

    Parameters
    ----------
    imu : object
        ``t``, ``specific_force``, ``angular_rate``.
    poses : object
        ``t`` (K,) s, ``position`` (K, 3) m, ``rotation`` (K, 3, 3) R_nb (e.g.
        ``load_kitti("seq00").orb_slam2``: real ORB-SLAM2).
    gravity : array_like, shape (3,)
        g_n, m/s².
    sigma_position : float
        σ per axis of pose k's position, m.
    sigma_attitude_deg : float
        σ per axis of its attitude, degrees (tilt and heading alike).
    k : int, optional
        Index of the pose to start from, 1 ≤ k < K; default the first k whose pose k − 1
        lies inside the IMU record (on sequence 00 the IMU starts at 1.41 s, so k = 15).
    config : EskfConfig or str
        Source of the bias σ's.

    Returns
    -------
    Initialisation
    """
    t, f, w, _ = _imu_arrays(imu)
    for name in ("t", "position", "rotation"):
        if not hasattr(poses, name):
            raise ValueError(f"poses must have t (K,), position (K, 3) and rotation (K, 3, 3); missing {name!r}")
    obs = PoseObservations(poses.t, poses.position, poses.rotation)
    if k is None:
        k = int(np.searchsorted(obs.t, t[0], side="left")) + 1
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or not 1 <= k < len(obs.t):
        raise ValueError(f"k must be an integer index with 1 <= k < {len(obs.t)} (a pose before it is needed), "
                         f"got {k!r}")
    sp = as_scalar(sigma_position, "sigma_position", allow_zero=True)
    sa = as_scalar(sigma_attitude_deg, "sigma_attitude_deg", allow_zero=True) * _DEG
    g_vec = as_vector(gravity, "gravity", 3)
    t_a, t_b = float(obs.t[k - 1]), float(obs.t[k])
    if t_a < t[0] or t_b >= t[-1]:
        raise ValueError(f"poses {k - 1} and {k} ({t_a:.3f}–{t_b:.3f} s) must lie inside the IMU record "
                         f"[{t[0]:.3f}, {t[-1]:.3f}] s")
    k_a = int(np.searchsorted(t, t_a, side="left"))
    R_carried = _relative_attitude(t, f, w, k_a, obs.rotation[k - 1], g_vec,
                                   int(np.searchsorted(t, t_b, side="right")) + 1)
    k_in = np.flatnonzero((t >= t_a) & (t <= t_b))
    if len(k_in) < 2:
        raise ValueError(f"poses {k - 1} and {k} enclose fewer than two IMU samples")
    acc = np.einsum("njk,nk->nj", R_carried[k_in - k_a], f[k_in]) + g_vec
    v_b = lag_corrected_velocity(obs.position[k - 1], obs.position[k], t_a, t_b, t[k_in], acc)
    k0 = int(np.searchsorted(t, t_b, side="left"))
    R0 = obs.rotation[k] @ so3.exp(0.5 * (w[k0 - 1] + w[k0]) * (t[k0] - t_b)) if k0 > 0 else obs.rotation[k]
    p0 = obs.position[k] + v_b * (t[k0] - t_b)
    sv = math.sqrt(2.0) * sp / (t_b - t_a)
    sig = {"position": np.full(3, sp), "velocity": np.full(3, sv), "tilt": sa, "heading": sa}
    P0 = initial_covariance(R0, sig["position"], sig["velocity"], sa, sa, config)
    return Initialisation("pose (visual odometry)", k0, float(t[k0]), eskf.NominalState(p0, v_b, R0), P0, sig,
                          None, (t_a, t_b), float(np.linalg.norm((obs.position[k] - obs.position[k - 1])[:2])),
                          float("nan"))


# ---------------------------------------------------------------------------------------
# Scoring runs against the truth
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RunErrors:
    """Errors of one ESKF run against the ground truth: at the start and at the truth's times after it.

    The first row is the initial state against the truth interpolated to the start time
    (with P̂₀); the others are the filter's output at the truth's pose times.

    The attitude error δθ = Log(R_trueᵀ R̂) (body frame, nominal − true) is shown in the
    navigation frame, R_true δθ: its z component is the heading error, its horizontal
    part the tilt error; the σ's are rotated the same way.

    Attributes
    ----------
    label : str
    t : numpy.ndarray, shape (K,)
        Times, s.
    position_error : numpy.ndarray, shape (K,)
        |p̂ − p|, m.
    position_sigma : numpy.ndarray, shape (K,)
        √(trace P_pp), the filter's RMS of that norm, m.
    heading_error : numpy.ndarray, shape (K,)
        Signed heading error, rad.
    heading_sigma : numpy.ndarray, shape (K,)
        Its σ from P, rad.
    tilt_error : numpy.ndarray, shape (K,)
        |horizontal part of the attitude error|, rad.
    tilt_sigma : numpy.ndarray, shape (K,)
        √(σ_x² + σ_y²) of the navigation-frame attitude error, rad.
    nees : numpy.ndarray, shape (K,)
        6-dof pose NEES (position and attitude).
    position, rotation : numpy.ndarray, shapes (K, 3), (K, 3, 3)
        The estimate itself.
    """

    label: str
    t: np.ndarray
    position_error: np.ndarray
    position_sigma: np.ndarray
    heading_error: np.ndarray
    heading_sigma: np.ndarray
    tilt_error: np.ndarray
    tilt_sigma: np.ndarray
    nees: np.ndarray
    position: np.ndarray = field(repr=False)
    rotation: np.ndarray = field(repr=False)


def run_errors(excerpt, initial, P0, k0: int, *, config="kitti_gnss", gnss=None, lidar=None,
               label: str = "") -> RunErrors:
    """Run the ESKF from (``initial``, ``P0``) at IMU sample ``k0`` and score it against the truth.

    Parameters
    ----------
    excerpt : KittiExcerpt
        Supplies the IMU (real), gravity and the ground truth (real).
    initial : eskf.NominalState or NavState
        The state at ``excerpt.imu.t[k0]``.
    P0 : array_like, shape (15, 15)
        Its covariance.
    k0 : int
        Start index into the IMU.
    config : EskfConfig or str
    gnss, lidar : observation records, optional
        What the filter fuses (e.g. ``excerpt.gnss.observations()``: simulated noise on the
        real OXTS positions; ``excerpt.lidar``: simulated poses). At least one.
    label : str
        Name of the run.

    Returns
    -------
    RunErrors
    """
    if gnss is None and lidar is None:
        raise ValueError("run_errors needs gnss or lidar observations (or both)")
    truth = excerpt.truth
    x0 = eskf.NominalState.from_nav(initial) if not isinstance(initial, eskf.NominalState) else initial
    res = eskf.run(excerpt.imu, x0, config, excerpt.gravity, gnss=gnss, lidar=lidar, start=k0, P0=P0,
                   output_times=truth.t, clip_output_times=True)
    r = res.at(truth.t)
    k = np.searchsorted(truth.t, r.t - 1e-6)
    t0 = float(excerpt.imu.t[k0])
    start = truth.state_at(t0)                     # the truth interpolated to the start
    t = np.concatenate([[t0], r.t])
    p = np.concatenate([x0.position[None], r.position])
    R = np.concatenate([x0.rotation[None], r.rotation])
    P = np.concatenate([np.asarray(P0, dtype=float)[None], r.P])
    p_true = np.concatenate([start.position[None], truth.position[k]])
    R_true = np.concatenate([start.rotation[None], truth.rotation[k]])
    return _scored(label, t, p, R, P, p_true, R_true)


def _scored(label, t, p, R, P, p_true, R_true) -> RunErrors:
    """:class:`RunErrors` of estimates (p, R, P) against true poses (p_true, R_true) at times t."""
    e_p = p - p_true
    d_theta = so3.log(np.swapaxes(R_true, 1, 2) @ R)                   # Log(R_trueᵀ R̂), body frame
    err_n = np.einsum("kij,kj->ki", R_true, d_theta)                   # R_true δθ, navigation frame
    P_th_n = R_true @ P[:, eskf.IDX_TH, eskf.IDX_TH] @ np.swapaxes(R_true, 1, 2)
    e_pose = np.concatenate([e_p, d_theta], axis=1)
    nees = metrics.nees(e_pose, P[:, POSE_INDEX][:, :, POSE_INDEX])
    return RunErrors(label, t, np.linalg.norm(e_p, axis=1),
                     np.sqrt(np.trace(P[:, eskf.IDX_P, eskf.IDX_P], axis1=1, axis2=2)),
                     err_n[:, 2], np.sqrt(P_th_n[:, 2, 2]), np.linalg.norm(err_n[:, 0:2], axis=1),
                     np.sqrt(P_th_n[:, 0, 0] + P_th_n[:, 1, 1]), nees, p, R)


def settling_time(t, values, threshold) -> float:
    """The first time from which ``values`` stay at or below ``threshold`` to the end.

    Parameters
    ----------
    t : array_like, shape (K,)
        Times, s, increasing.
    values : array_like, shape (K,)
        A non-negative error (e.g. |p̂ − p|).
    threshold : float
        The error to reach.

    Returns
    -------
    float
        That time, s; ``t[0]`` if the values never exceed the threshold, ``inf`` if the
        last value exceeds it.
    """
    t = as_vector(t, "t")
    if len(t) > 1 and not (np.diff(t) > 0).all():
        raise ValueError(f"t must be strictly increasing, not at index {int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1}")
    values = as_vector(values, "values", len(t))
    threshold = as_scalar(threshold, "threshold", allow_zero=True)
    above = np.flatnonzero(values > threshold)
    if above.size == 0:
        return float(t[0])
    if above[-1] == len(t) - 1:
        return math.inf
    return float(t[above[-1] + 1])


@dataclass(frozen=True)
class StartComparison:
    """The same filter started from an initialisation and from the truth.

    Attributes
    ----------
    from_initialisation, from_truth : RunErrors
    position_difference : numpy.ndarray, shape (K,)
        |p̂_init − p̂_truth| between the two estimates, m.
    attitude_difference : numpy.ndarray, shape (K,)
        Angle of R̂_truthᵀ R̂_init, rad.
    agreement_time : float
        First time from which both differences stay within the tolerances, s (inf: never).
    position_tolerance : float
        m.
    attitude_tolerance : float
        rad.
    """

    from_initialisation: RunErrors
    from_truth: RunErrors
    position_difference: np.ndarray
    attitude_difference: np.ndarray
    agreement_time: float
    position_tolerance: float
    attitude_tolerance: float


def compare_starts(excerpt, init: Initialisation, *, config="kitti_gnss", gnss=None, lidar=None,
                   position_tolerance: float = 0.1, attitude_tolerance_deg: float = 0.1) -> StartComparison:
    """Run the ESKF from ``init`` and from the truth at the same IMU sample, and compare.

    The truth start uses the configuration's own P̂₀ (its prior σ's), the initialisation
    its derived :attr:`Initialisation.P0`. Both fuse the same observations.

    Parameters
    ----------
    excerpt : KittiExcerpt
    init : Initialisation
    config : EskfConfig or str
    gnss, lidar : observation records, optional
        Default: ``excerpt.gnss.observations()`` (simulated noise on the real positions).
    position_tolerance : float
        Agreement threshold on |p̂_init − p̂_truth|, m.
    attitude_tolerance_deg : float
        Agreement threshold on the angle between the two attitudes, degrees.

    Returns
    -------
    StartComparison
    """
    if not isinstance(init, Initialisation):
        raise ValueError(f"init must be an Initialisation (from initialise_from_gnss or initialise_from_pose), "
                         f"got {type(init).__name__}")
    tol_p = as_scalar(position_tolerance, "position_tolerance")
    tol_a = as_scalar(attitude_tolerance_deg, "attitude_tolerance_deg") * _DEG
    if gnss is None and lidar is None:
        gnss = excerpt.gnss.observations()
    cfg = _config(config)
    truth_state = excerpt.truth.state_at(init.t0)
    a = run_errors(excerpt, init.state, init.P0, init.k0, config=cfg, gnss=gnss, lidar=lidar,
                   label="from the initialisation")
    b = run_errors(excerpt, truth_state, eskf.initial_covariance(cfg), init.k0, config=cfg, gnss=gnss,
                   lidar=lidar, label="from the truth")
    dp = np.linalg.norm(a.position - b.position, axis=1)
    da = so3.angle(np.swapaxes(b.rotation, 1, 2) @ a.rotation)
    agree = settling_time(a.t, np.maximum(dp / tol_p, da / tol_a), 1.0)
    return StartComparison(a, b, dp, da, agree, tol_p, tol_a)


@dataclass(frozen=True)
class P0Run:
    """One run of :func:`p0_scaling`.

    Attributes
    ----------
    scale : float
        The factor P̂₀ was multiplied by.
    errors : RunErrors
    time_to_position : float
        :func:`settling_time` of the position error to the position threshold, s after t0.
    time_to_attitude : float
        The same for the attitude error's angle, √(heading² + tilt²), and the attitude
        threshold, s after t0.
    mean_nees : float
        Mean 6-dof pose NEES over the run.
    """

    scale: float
    errors: RunErrors
    time_to_position: float
    time_to_attitude: float
    mean_nees: float


def p0_scaling(excerpt, init: Initialisation, scales=(0.01, 1.0, 100.0), *, config="kitti_gnss", gnss=None,
               lidar=None, position_threshold: float = 1.0, attitude_threshold_deg: float = 1.0) -> list[P0Run]:
    """The seed lecture's advice, measured: the same wrong start with P̂₀ scaled.

    The filter starts from ``init.state`` (wrong by whatever the initialisation got
    wrong) with ``scale × init.P0`` for each scale, and fuses the same observations. The
    seed says a P̂₀ set larger than the noise converges faster; a small one claims
    certainty the start does not have, so the filter discounts the observations that
    would correct it, and its NEES shows it.

    Measured on ``stop_go`` (see ``tests/test_initialisation.py``): with 10 Hz lidar poses
    (simulated) P̂₀ × 0.01 starts with a pose NEES in the hundreds and takes longer to
    reach 1 m and 1°, while × 1 and × 100 converge at the first pose. With 1 Hz GNSS
    fixes alone (simulated noise of 1 m), heading is seen only through the car's
    accelerations, and × 100 lets the fixes' noise turn the heading by many degrees: the
    advice holds for what the observations pin down quickly, not for what they barely see.

    Parameters
    ----------
    excerpt : KittiExcerpt
    init : Initialisation
    scales : sequence of float
        Positive factors on P̂₀ (on the variances: × 100 is × 10 on every σ).
    config : EskfConfig or str
    gnss, lidar : observation records, optional
        Default: ``excerpt.gnss.observations()``.
    position_threshold : float
        Error to reach for :attr:`P0Run.time_to_position`, m.
    attitude_threshold_deg : float
        Attitude error angle to reach for :attr:`P0Run.time_to_attitude`, degrees.

    Returns
    -------
    list of P0Run
        In the order of ``scales``.
    """
    if not isinstance(init, Initialisation):
        raise ValueError(f"init must be an Initialisation, got {type(init).__name__}")
    if not hasattr(scales, "__iter__") or isinstance(scales, str):
        raise ValueError(f"scales must be a sequence of positive numbers, got {scales!r}")
    scales = [as_scalar(s, f"scales[{i}]") for i, s in enumerate(scales)]
    if not scales:
        raise ValueError("scales must hold at least one factor")
    thr_p = as_scalar(position_threshold, "position_threshold")
    thr_a = as_scalar(attitude_threshold_deg, "attitude_threshold_deg") * _DEG
    if gnss is None and lidar is None:
        gnss = excerpt.gnss.observations()
    cfg = _config(config)
    runs = []
    for s in scales:
        e = run_errors(excerpt, init.state, s * init.P0, init.k0, config=cfg, gnss=gnss, lidar=lidar,
                       label=f"P̂₀ × {s:g}")
        runs.append(P0Run(s, e, settling_time(e.t, e.position_error, thr_p) - init.t0,
                          settling_time(e.t, np.hypot(e.heading_error, e.tilt_error), thr_a) - init.t0,
                          float(np.mean(e.nees))))
    return runs


#: The blocks of the 15-dof error state δx = [δp, δv, δθ, δb_a, δb_ω].
ERROR_BLOCKS = {"position": slice(0, 3), "velocity": slice(3, 6), "attitude": slice(6, 9),
                "accel_bias": slice(9, 12), "gyro_bias": slice(12, 15)}


def scale_blocks(P0, factors) -> np.ndarray:
    """P̂₀ with the variances of some blocks multiplied: D P̂₀ D, D = diag(√factor per entry).

    The correlations between entries are kept; each σ of a block scales by √factor.

    Parameters
    ----------
    P0 : array_like, shape (15, 15)
        A covariance of δx.
    factors : mapping of str to float
        Block name (a key of :data:`ERROR_BLOCKS`) -> positive factor on its variances;
        blocks not named keep factor 1.

    Returns
    -------
    numpy.ndarray, shape (15, 15)
    """
    P0 = as_covariance(P0, "P0", 15, psd=True)
    if not isinstance(factors, Mapping):
        raise ValueError(f"factors must be a mapping of block name -> factor, got {type(factors).__name__}")
    d = np.ones(15)
    for name, factor in dict(factors).items():
        if name not in ERROR_BLOCKS:
            raise ValueError(f"factors: unknown block {name!r}; known: {', '.join(ERROR_BLOCKS)}")
        d[ERROR_BLOCKS[name]] = math.sqrt(as_scalar(factor, f"factors[{name!r}]"))
    return symmetrise(d[:, None] * P0 * d[None, :])


def p0_block_study(excerpt, standstill, variants, seeds, *, config="kitti_gnss", last: float = 10.0) -> dict:
    """Which block of a too-wide P̂₀ does the harm: heading error per variant and GNSS noise draw.

    For each seed the GNSS fixes are drawn anew (``simulate_gnss`` on the excerpt's real
    positions; seed None: the shipped draw), the filter is initialised from them
    (:func:`initialise_from_gnss` after ``standstill``), and run from that start once per
    variant, with P̂₀ scaled block by block (:func:`scale_blocks`). One thing changes at a
    time: the start and the fixes are the same for every variant of a seed.

    Parameters
    ----------
    excerpt : KittiExcerpt
        Real IMU and truth (e.g. ``load_kitti("stop_go")``).
    standstill : array_like, shape (2,)
        A span of :func:`detect_standstill`.
    variants : mapping of str to mapping
        Label -> ``factors`` of :func:`scale_blocks` (``{}``: the derived P̂₀).
    seeds : sequence of int or None
        GNSS noise draws; None is the excerpt's shipped draw.
    config : EskfConfig or str
        The GNSS filter's configuration.
    last : float
        The heading error is the RMS over the run's last ``last`` seconds, degrees.

    Returns
    -------
    dict of str to numpy.ndarray, shape (len(seeds),)
        Label -> RMS heading error over the last ``last`` s, degrees, per seed.
    """
    seeds = list(seeds)
    if not seeds:
        raise ValueError("seeds must hold at least one seed (or None for the shipped draw)")
    if not variants:
        raise ValueError("variants must name at least one P̂₀ scaling")
    last = as_scalar(last, "last")
    cfg = _config(config)
    out = {label: np.empty(len(seeds)) for label in variants}
    for i, seed in enumerate(seeds):
        gnss = excerpt.gnss if seed is None else simulate_gnss(excerpt.gnss, seed, excerpt.gnss.sigma)
        fixes = gnss.observations()
        init = initialise_from_gnss(excerpt.imu, fixes, excerpt.gravity, standstill, config=cfg)
        for label, factors in variants.items():
            e = run_errors(excerpt, init.state, scale_blocks(init.P0, factors), init.k0, config=cfg, gnss=fixes)
            tail = e.t >= e.t[-1] - last
            out[label][i] = float(np.rad2deg(metrics.rmse(e.heading_error[tail], np.zeros(tail.sum()), axis=None)))
    return out
