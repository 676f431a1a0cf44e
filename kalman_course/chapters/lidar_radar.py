"""Chapter 05: a CTRV target seen by a lidar and a radar, and a CTRV EKF on KITTI.

- :func:`ctrv_lidar_radar`: the seeded scenario of the lecture's article: a CTRV target
  observed alternately by a lidar (p_x, p_y) and a radar (range, bearing, range rate),
  built on the course's one CTRV model and radar h(x) (:mod:`kalman_course.symbolic`);
- :func:`read_udacity_log`: the same structure read from a log in the text format of the
  Udacity lidar/radar project (``obj_pose-laser-radar-synthetic-input.txt``);
- :func:`figure_eight_lidar_radar`: the same sensors watching a smooth figure-eight that
  none of the filters' motion models generates (the truth of the lecture's comparison);
- :func:`fuse_lidar_radar`: the reference CTRV EKF (or IEKF) over either, predicting over
  each measurement's own time step; ``model="cv"`` runs the article's constant-velocity
  model in the same filter;
- :func:`compare_cv_ctrv`: CV against CTRV on the same simulated measurements over seeds,
  each model's process noise tuned by the same rule on other seeds;
- :func:`run_kitti_ctrv`: a CTRV EKF on a KITTI excerpt with 1 Hz GNSS and the gyro's yaw
  rate; :func:`kitti_sigma_a_sweep` runs it over σ_a values and simulated GNSS draws, and
  :func:`kitti_acceleration` measures the real car's along-track acceleration.

CTRV state x = [p_x (m), p_y (m), v (m/s), ψ (rad), ω (rad/s)]; process noise
w = [ν_a (m/s²), ν_ψ̈ (rad/s²)] held constant over a step. Bearings are wrapped to
(−π, π] (:func:`kalman_course.core.angles.wrap_angle`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterator

import numpy as np

from kalman_course import symbolic
from kalman_course.core.angles import wrap_angle
from kalman_course.core.linalg import symmetrise
from kalman_course.core.validation import (as_covariance, as_flag, as_int, as_path, as_real_array, as_rows,
                                           as_scalar, as_seed, as_vector, require_file)
from kalman_course.data.kitti import simulate_gnss
from kalman_course.evaluation.metrics import nees, position_rmse, rmse
from kalman_course.filters.ekf import (LIDAR_G, ekf_predict, ekf_update, iekf_update, lidar_observation,
                                      radar_residual)

__all__ = [
    "R_LIDAR_DEFAULT", "R_RADAR_DEFAULT", "Measurement", "CTRVScenario", "ctrv_lidar_radar", "read_udacity_log",
    "figure_eight_lidar_radar", "ctrv_to_cartesian", "initial_ctrv_state", "radar_position_fix", "FusionResult",
    "cartesian_rmse", "fuse_lidar_radar", "UDACITY_RUBRIC", "ModelComparison", "compare_cv_ctrv", "position_nees",
    "KittiCTRVResult", "run_kitti_ctrv", "KittiAcceleration", "kitti_acceleration", "SigmaSweep", "kitti_sigma_a_sweep",
]

#: Lidar noise of the seed article: σ = 0.15 m on x and y.
R_LIDAR_DEFAULT = ((0.0225, 0.0), (0.0, 0.0225))
#: Radar noise of the seed article: σ = 0.3 m (range), 0.03 rad (bearing), 0.3 m/s (range rate).
R_RADAR_DEFAULT = ((0.09, 0.0, 0.0), (0.0, 0.0009, 0.0), (0.0, 0.0, 0.09))


# ---------------------------------------------------------------------------------------
# the scenario structure
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Measurement:
    """One sensor reading.

    Attributes
    ----------
    t : float
        Time, s.
    sensor : str
        "lidar" (z = [p_x, p_y] in m) or "radar" (z = [ρ m, φ rad, ρ̇ m/s]).
    z : numpy.ndarray, shape (2,) or (3,)
    R : numpy.ndarray, shape (2, 2) or (3, 3)
        The sensor's noise covariance.
    index : int
        Row of the scenario (index into its ``t`` and ``x``).
    """

    t: float
    sensor: str
    z: np.ndarray
    R: np.ndarray
    index: int


@dataclass(frozen=True, eq=False)
class CTRVScenario:
    """A target observed by a lidar and a radar at the origin, one sensor per row.

    Attributes
    ----------
    t : numpy.ndarray, shape (n,)
        Measurement times, s, in row order (not necessarily evenly spaced).
    x : numpy.ndarray, shape (n, 5)
        True CTRV state at each time: [p_x (m), p_y (m), v (m/s), ψ (rad), ω (rad/s)].
        A log that does not give ω holds NaN there.
    sensor : numpy.ndarray of str, shape (n,)
        "lidar" or "radar" for each row.
    lidar_index, radar_index : numpy.ndarray of int, shapes (L,), (M,)
        Rows of the lidar and of the radar measurements; together they are every row.
    lidar_z : numpy.ndarray, shape (L, 2)
        Lidar measurements [p_x, p_y], m.
    radar_z : numpy.ndarray, shape (M, 3)
        Radar measurements [ρ (m), φ (rad), ρ̇ (m/s)].
    R_lidar : numpy.ndarray, shape (2, 2)
    R_radar : numpy.ndarray, shape (3, 3)
    sigma_a : float
        Longitudinal acceleration noise σ_a, m/s² (the filter's default process noise).
    sigma_yaw_acc : float
        Yaw acceleration noise σ_ψ̈, rad/s².
    dt : float or None
        Interval of an evenly sampled scenario, s; None for a log.
    x0 : numpy.ndarray, shape (5,), or None
        True state at t = 0 of a simulated scenario (its first row is at t = dt).
    seed : int or None
        Seed of a simulated scenario.
    """

    t: np.ndarray
    x: np.ndarray
    sensor: np.ndarray
    lidar_index: np.ndarray
    lidar_z: np.ndarray
    radar_index: np.ndarray
    radar_z: np.ndarray
    R_lidar: np.ndarray
    R_radar: np.ndarray
    sigma_a: float
    sigma_yaw_acc: float
    dt: float | None = None
    x0: np.ndarray | None = None
    seed: int | None = None

    def __post_init__(self):
        n = len(self.t)
        if np.shape(self.t) != (n,) or not np.isfinite(self.t).all():
            raise ValueError(f"t must be a finite 1-D array of times, got shape {np.shape(self.t)}")
        if np.shape(self.x) != (n, 5):
            raise ValueError(f"x must have shape ({n}, 5), got {np.shape(self.x)}")
        if np.shape(self.sensor) != (n,):
            raise ValueError(f"sensor must have shape ({n},), got {np.shape(self.sensor)}")
        if np.shape(self.lidar_z) != (len(self.lidar_index), 2):
            raise ValueError(f"lidar_z must have shape ({len(self.lidar_index)}, 2), got {np.shape(self.lidar_z)}")
        if np.shape(self.radar_z) != (len(self.radar_index), 3):
            raise ValueError(f"radar_z must have shape ({len(self.radar_index)}, 3), got {np.shape(self.radar_z)}")
        rows = np.sort(np.concatenate([self.lidar_index, self.radar_index]))
        if not np.array_equal(rows, np.arange(n)):
            raise ValueError("lidar_index and radar_index must together hold every row 0 … n−1 once")

    @property
    def lidar_t(self) -> np.ndarray:
        """Lidar measurement times, s, shape (L,)."""
        return self.t[self.lidar_index]

    @property
    def radar_t(self) -> np.ndarray:
        """Radar measurement times, s, shape (M,)."""
        return self.t[self.radar_index]

    def measurements(self) -> Iterator[Measurement]:
        """Yield every measurement in row order."""
        lidar_row = {int(k): i for i, k in enumerate(self.lidar_index)}
        radar_row = {int(k): i for i, k in enumerate(self.radar_index)}
        for k in range(len(self.t)):
            if k in lidar_row:
                yield Measurement(float(self.t[k]), "lidar", self.lidar_z[lidar_row[k]], self.R_lidar, k)
            else:
                yield Measurement(float(self.t[k]), "radar", self.radar_z[radar_row[k]], self.R_radar, k)

    def __len__(self) -> int:
        return len(self.t)


def _split_by_sensor(sensor: np.ndarray):
    rows = np.arange(len(sensor))
    return rows[sensor == "lidar"], rows[sensor == "radar"]


# ---------------------------------------------------------------------------------------
# the seeded scenario
# ---------------------------------------------------------------------------------------

def _measure(x: np.ndarray, rng, R_l: np.ndarray, R_r: np.ndarray):
    """Alternate lidar and radar measurements of the states x (n, 5), lidar first; lidar noise drawn first."""
    sensor = np.where(np.arange(len(x)) % 2 == 0, "lidar", "radar")
    lidar_index, radar_index = _split_by_sensor(sensor)
    lidar_noise = rng.standard_normal((len(lidar_index), 2)) @ np.linalg.cholesky(R_l).T
    radar_noise = rng.standard_normal((len(radar_index), 3)) @ np.linalg.cholesky(R_r).T
    lidar_z = x[lidar_index, :2] + lidar_noise
    radar_z = np.array([symbolic.radar_observation(state) for state in x[radar_index]]) + radar_noise
    radar_z[:, 1] = wrap_angle(radar_z[:, 1])
    return sensor, lidar_index, lidar_z, radar_index, radar_z


def ctrv_lidar_radar(seed: int, duration: float = 25.0, dt: float = 0.05, sigma_a: float = 3.0,
                     sigma_yaw_acc: float = 0.3, R_lidar=R_LIDAR_DEFAULT, R_radar=R_RADAR_DEFAULT,
                     x0=(5.0, 2.0, 5.0, 0.5, 0.1)) -> CTRVScenario:
    """Simulate a CTRV target observed by interleaved lidar and radar measurements.

    The truth follows the course's CTRV model (``symbolic.ctrv_step``) from ``x0`` with
    noise ν_a ~ N(0, σ_a²) and ν_ψ̈ ~ N(0, σ_ψ̈²) drawn for every step. A measurement is
    taken every ``dt`` seconds, alternately lidar (first, at t = dt) and radar. Lidar:
    z = [p_x, p_y] + N(0, R_lidar); radar: z = h(x) + N(0, R_radar) with the course's
    radar model h (``symbolic.radar_observation``) and φ wrapped to (−π, π]. The noise
    values are those of the seed article: R_lidar = diag(0.0225, 0.0225),
    R_radar = diag(0.09, 0.0009, 0.09), σ_a = 3 m/s².

    Parameters
    ----------
    seed : int
        Seed; draws ν_a (n,), ν_ψ̈ (n,), then the lidar noise (L, 2), then the radar noise
        (M, 3), all standard normal (the measurement noise through a Cholesky factor of R).
    duration : float
        Length of the scenario, s; n = round(duration/dt) measurements.
    dt : float
        Interval between consecutive measurements (of either sensor), s.
    sigma_a : float
        Longitudinal acceleration noise, m/s².
    sigma_yaw_acc : float
        Yaw acceleration noise, rad/s².
    R_lidar : array_like, shape (2, 2)
    R_radar : array_like, shape (3, 3)
    x0 : array_like, shape (5,)
        Initial state [p_x, p_y, v, ψ, ω].

    Returns
    -------
    CTRVScenario
    """
    seed = as_seed(seed)
    duration = as_scalar(duration, "duration")
    dt = as_scalar(dt, "dt")
    sigma_a = as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_yaw_acc = as_scalar(sigma_yaw_acc, "sigma_yaw_acc", allow_zero=True)
    R_l = as_covariance(R_lidar, "R_lidar", 2, positive_definite=True)
    R_r = as_covariance(R_radar, "R_radar", 3, positive_definite=True)
    x0 = as_vector(x0, "x0", 5)
    n = int(round(duration / dt))
    if n < 2:
        raise ValueError(f"duration must cover at least two measurements of dt = {dt} s, got {duration}")
    rng = np.random.default_rng(seed)
    nu = np.column_stack([sigma_a * rng.standard_normal(n), sigma_yaw_acc * rng.standard_normal(n)])
    x = np.empty((n, 5))
    state = x0.copy()
    for k in range(n):
        state = symbolic.ctrv_step(state, dt, nu[k])
        x[k] = state
    t = dt * np.arange(1, n + 1)
    sensor, lidar_index, lidar_z, radar_index, radar_z = _measure(x, rng, R_l, R_r)
    return CTRVScenario(t, x, sensor, lidar_index, lidar_z, radar_index, radar_z, R_l, R_r, sigma_a,
                        sigma_yaw_acc, dt=dt, x0=x0.copy(), seed=seed)


def figure_eight_lidar_radar(seed: int, duration: float = 25.0, dt: float = 0.05, R_lidar=R_LIDAR_DEFAULT,
                             R_radar=R_RADAR_DEFAULT, sigma_a: float = 3.0,
                             sigma_yaw_acc: float = 0.3) -> CTRVScenario:
    """A smooth figure-eight target that follows none of the filters' models, seen by lidar and radar.

    The truth is a Lissajous curve, p(t) = c + [A sin(Ωt + θ), B sin(2(Ωt + θ))] with
    Ω = 2π/period: speed and turn rate change smoothly and all the time, so neither a
    constant-velocity nor a constant-turn-rate model (nor their white-noise accelerations)
    generates it. The seed draws the size (A ~ U(8, 14) m, B ~ U(4, 7) m), the period
    (U(20, 30) s) and the phase θ ~ U(0, 2π); the centre is c = (A + 5, 0) m, so the
    target stays at least 5 m from the radar at the origin. Speed and heading come from
    the exact derivative, ω from the curvature (ω = (v_x a_y − v_y a_x)/v²). The
    measurements are drawn as in :func:`ctrv_lidar_radar`: every ``dt`` alternately lidar
    (first, at t = dt) and radar, with noise R_lidar and R_radar.

    Parameters
    ----------
    seed : int
        Seed; draws A, B, the period and θ (four uniforms), then the lidar noise (L, 2),
        then the radar noise (M, 3), standard normal through a Cholesky factor of R.
    duration : float
        Length, s; n = round(duration/dt) measurements.
    dt : float
        Interval between consecutive measurements (of either sensor), s.
    R_lidar : array_like, shape (2, 2)
    R_radar : array_like, shape (3, 3)
    sigma_a, sigma_yaw_acc : float
        Process noise stored on the scenario as the filter's default (m/s², rad/s²); the
        truth does not use them.

    Returns
    -------
    CTRVScenario
        ``x`` holds [p_x, p_y, v, ψ (unwrapped), ω]; ``x0`` the state at t = 0.
    """
    seed = as_seed(seed)
    duration = as_scalar(duration, "duration")
    dt = as_scalar(dt, "dt")
    sigma_a = as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_yaw_acc = as_scalar(sigma_yaw_acc, "sigma_yaw_acc", allow_zero=True)
    R_l = as_covariance(R_lidar, "R_lidar", 2, positive_definite=True)
    R_r = as_covariance(R_radar, "R_radar", 3, positive_definite=True)
    n = int(round(duration / dt))
    if n < 2:
        raise ValueError(f"duration must cover at least two measurements of dt = {dt} s, got {duration}")
    rng = np.random.default_rng(seed)
    A, B = rng.uniform(8.0, 14.0), rng.uniform(4.0, 7.0)
    Om, theta = 2.0 * np.pi / rng.uniform(20.0, 30.0), rng.uniform(0.0, 2.0 * np.pi)
    t_all = dt * np.arange(0, n + 1)                    # t = 0 (x0), then the n measurement times
    u = Om * t_all + theta
    pos = np.column_stack([A + 5.0 + A * np.sin(u), B * np.sin(2 * u)])
    vel = np.column_stack([A * Om * np.cos(u), 2 * B * Om * np.cos(2 * u)])
    acc = np.column_stack([-A * Om**2 * np.sin(u), -4 * B * Om**2 * np.sin(2 * u)])
    speed = np.hypot(vel[:, 0], vel[:, 1])              # > 0: v_x = 0 only where |v_y| = 2BΩ
    yaw = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    yaw_rate = (vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / speed**2
    states = np.column_stack([pos, speed, yaw, yaw_rate])
    x, t = states[1:], t_all[1:]
    sensor, lidar_index, lidar_z, radar_index, radar_z = _measure(x, rng, R_l, R_r)
    return CTRVScenario(t, x, sensor, lidar_index, lidar_z, radar_index, radar_z, R_l, R_r, sigma_a,
                        sigma_yaw_acc, dt=dt, x0=states[0].copy(), seed=seed)


# ---------------------------------------------------------------------------------------
# the Udacity lidar/radar log
# ---------------------------------------------------------------------------------------

#: Fields per line of the Udacity log: sensor letter, measurement, timestamp (µs), truth
#: [p_x, p_y, v_x, v_y] and, in the UKF project's files, the true yaw and yaw rate.
_UDACITY_FIELDS = {"L": (8, 10), "R": (9, 11)}
#: How far beyond ±π a logged bearing may lie (rounding of an atan2 result written as text), rad.
_BEARING_SLACK = 1e-3


def _parse_udacity_line(fields: list[str], where: str):
    """(sensor, z, timestamp_us, truth (5,)) of one log line; ValueError naming ``where``."""
    letter = fields[0]
    if letter not in _UDACITY_FIELDS:
        raise ValueError(f"{where}: the first field must be 'L' (lidar) or 'R' (radar), got {letter!r}")
    counts = _UDACITY_FIELDS[letter]
    if len(fields) not in counts:
        raise ValueError(f"{where}: a '{letter}' line has {counts[0]} fields ({counts[1]} with the true yaw "
                         f"and yaw rate), got {len(fields)}")
    m = 2 if letter == "L" else 3
    numbers = []
    for k, text in enumerate(fields[1:], start=2):
        try:
            numbers.append(float(text))
        except ValueError:
            raise ValueError(f"{where}: field {k} must be a number, got {text!r}") from None
    if not np.isfinite(numbers).all():
        raise ValueError(f"{where}: every number must be finite, got {' '.join(fields[1:])}")
    if letter == "R" and abs(numbers[1]) > np.pi + _BEARING_SLACK:
        raise ValueError(f"{where}: the bearing φ (field 3) must be in radians within [−π, π], got "
                         f"{fields[2]} (given in degrees?)")
    if letter == "R" and numbers[0] < 0.0:
        raise ValueError(f"{where}: the range ρ (field 2) must not be negative, got {fields[1]}")
    try:
        stamp = int(fields[m + 1])                     # exact: a float holds µs since 1970 only to ~1 µs
    except ValueError:
        raise ValueError(f"{where}: the timestamp (field {m + 2}) must be an integer number of µs, "
                         f"got {fields[m + 1]}") from None
    if not 0 <= stamp < 2**62:                         # held as int64 µs, differences included
        raise ValueError(f"{where}: the timestamp (field {m + 2}) must be a non-negative number of µs "
                         f"below 2^62, got {fields[m + 1]}")
    px, py, vx, vy = numbers[m + 1:m + 5]
    if len(numbers) > m + 5:
        yaw, yaw_rate = numbers[m + 5:m + 7]
    else:
        yaw, yaw_rate = np.arctan2(vy, vx), np.nan      # the EKF project's log gives no turn rate
    truth = np.array([px, py, np.hypot(vx, vy), yaw, yaw_rate])
    return ("lidar" if letter == "L" else "radar"), np.array(numbers[:m]), stamp, truth


def read_udacity_log(path, *, R_lidar=R_LIDAR_DEFAULT, R_radar=R_RADAR_DEFAULT, sigma_a: float = 3.0,
                     sigma_yaw_acc: float = 0.3) -> CTRVScenario:
    """Read a lidar/radar log in the Udacity project's text format.

    One measurement per line, fields separated by white space::

        L  p_x  p_y  timestamp_us  gt_p_x  gt_p_y  gt_v_x  gt_v_y  [gt_yaw  gt_yaw_rate]
        R  rho  phi  rho_dot  timestamp_us  gt_p_x  gt_p_y  gt_v_x  gt_v_y  [gt_yaw  gt_yaw_rate]

    (lengths m, angles rad, times µs; the bracketed truth comes with the UKF project's
    files). Blank lines are skipped. The log gives no noise model, so the sensors' R and
    the process noise are arguments, by default the article's values (those of
    :func:`ctrv_lidar_radar`).

    Parameters
    ----------
    path : str or path-like
    R_lidar : array_like, shape (2, 2)
    R_radar : array_like, shape (3, 3)
    sigma_a, sigma_yaw_acc : float
        Process noise stored on the scenario for :func:`fuse_lidar_radar`.

    Returns
    -------
    CTRVScenario
        ``t`` in seconds since the first line's timestamp, rows in file order (not sorted:
        :func:`fuse_lidar_radar` rejects time going backwards). The true state is
        [p_x, p_y, |v|, ψ, ω] with ψ = atan2(v_y, v_x) and ω = NaN when the log has no yaw
        columns. ``dt``, ``x0`` and ``seed`` are None.

    Raises
    ------
    ValueError
        For an empty log, a file that is not text, a malformed line, or a line whose format
        (with or without the yaw columns) differs from the first line's (a truncated line);
        the message names the file and the line number.
    """
    path = require_file(as_path(path, "path"), "a Udacity lidar/radar log (text)")
    R_l = as_covariance(R_lidar, "R_lidar", 2, positive_definite=True)
    R_r = as_covariance(R_radar, "R_radar", 3, positive_definite=True)
    sigma_a = as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_yaw_acc = as_scalar(sigma_yaw_acc, "sigma_yaw_acc", allow_zero=True)
    sensors, zs, stamps, truths = [], [], [], []
    with_yaw = None                  # the file's format, from its first line: every line must share it
    try:
        with path.open(encoding="utf-8") as lines:
            for number, line in enumerate(lines, start=1):
                fields = line.split()
                if not fields:
                    continue
                where = f"{path}, line {number}"
                sensor, z, stamp, truth = _parse_udacity_line(fields, where)
                has_yaw = len(fields) == _UDACITY_FIELDS[fields[0]][1]
                if with_yaw is None:
                    with_yaw = has_yaw
                elif has_yaw != with_yaw:
                    raise ValueError(f"{where}: {len(fields)} fields, {'with' if has_yaw else 'without'} the true "
                                     f"yaw and yaw rate, where the file's first line is "
                                     f"{'with' if with_yaw else 'without'} them (a truncated or joined line?)")
                sensors.append(sensor)
                zs.append(z)
                stamps.append(stamp)
                truths.append(truth)
    except UnicodeDecodeError as err:
        raise ValueError(f"{path} is not a text log (byte {err.start} is not UTF-8): is it the right file?") from None
    if not sensors:
        raise ValueError(f"{path} holds no measurements")
    sensor = np.array(sensors)
    lidar_index, radar_index = _split_by_sensor(sensor)
    t = (np.array(stamps, dtype=np.int64) - stamps[0]) * 1e-6          # integer µs first: exact
    lidar_z = np.array([zs[k] for k in lidar_index]).reshape(-1, 2)
    radar_z = np.array([zs[k] for k in radar_index]).reshape(-1, 3)
    return CTRVScenario(t, np.array(truths), sensor, lidar_index, lidar_z, radar_index, radar_z, R_l, R_r,
                        sigma_a, sigma_yaw_acc)


# ---------------------------------------------------------------------------------------
# the reference lidar + radar filter
# ---------------------------------------------------------------------------------------

def ctrv_to_cartesian(states) -> np.ndarray:
    """[p_x, p_y, v_x, v_y] (N, 4) of CTRV states (N, 5), with v_x = v cos ψ, v_y = v sin ψ."""
    s = as_real_array(states, "states")
    if s.ndim != 2 or s.shape[1] != 5:
        raise ValueError(f"states must have shape (N, 5), got {s.shape}")
    return np.column_stack([s[:, 0], s[:, 1], s[:, 2] * np.cos(s[:, 3]), s[:, 2] * np.sin(s[:, 3])])


def initial_ctrv_state(z_lidar, R_lidar, sigma_v=5.0, sigma_yaw=np.pi, sigma_yaw_rate=0.5):
    """Prior from a position fix: position measured, speed, heading and turn rate unknown.

    Parameters
    ----------
    z_lidar : array_like, shape (2,)
        Measured [p_x, p_y], m.
    R_lidar : array_like, shape (2, 2)
        Its covariance, m².
    sigma_v, sigma_yaw, sigma_yaw_rate : float
        Prior standard deviations of v (m/s), ψ (rad) and ω (rad/s).

    Returns
    -------
    x0 : ndarray, shape (5,)
        [z_x, z_y, 0, 0, 0].
    P0 : ndarray, shape (5, 5)
        diag(R_lidar, σ_v², σ_ψ², σ_ω²) (R_lidar as a block).
    """
    z = as_vector(z_lidar, "z_lidar", 2)
    R = as_covariance(R_lidar, "R_lidar", 2, psd=True)
    x0 = np.array([z[0], z[1], 0.0, 0.0, 0.0])
    P0 = np.zeros((5, 5))
    P0[:2, :2] = R
    P0[2, 2] = as_scalar(sigma_v, "sigma_v") ** 2
    P0[3, 3] = as_scalar(sigma_yaw, "sigma_yaw") ** 2
    P0[4, 4] = as_scalar(sigma_yaw_rate, "sigma_yaw_rate") ** 2
    return x0, P0


def radar_position_fix(z_radar, R_radar):
    """A radar reading as a position fix: p = ρ [cos φ, sin φ] and its covariance J R Jᵀ.

    Parameters
    ----------
    z_radar : array_like, shape (3,)
        [ρ (m), φ (rad), ρ̇ (m/s)].
    R_radar : array_like, shape (3, 3)
        Its covariance.

    Returns
    -------
    p : ndarray, shape (2,)
        Position, m.
    R_p : ndarray, shape (2, 2)
        J R_ρφ Jᵀ, with J = ∂p/∂(ρ, φ) the first-order propagation of the range and
        bearing noise.
    """
    rho, phi, _ = as_vector(z_radar, "z_radar", 3)
    R = as_covariance(R_radar, "R_radar", 3, psd=True)
    c, s = np.cos(phi), np.sin(phi)
    J = np.array([[c, -rho * s], [s, rho * c]])
    R_p = J @ R[:2, :2] @ J.T
    return rho * np.array([c, s]), symmetrise(R_p)


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
    model : str
        The filter's motion model: "ctrv" (``x_hat`` and ``P_hat`` in the CTRV layout,
        (N, 5) and (N, 5, 5)) or "cv" ([p_x, p_y, v_x, v_y], (N, 4) and (N, 4, 4)).
        ``truth`` is in the CTRV layout either way.
    """

    t: np.ndarray
    x_hat: np.ndarray
    P_hat: np.ndarray
    truth: np.ndarray
    rmse: dict
    iterations: np.ndarray
    model: str = "ctrv"

    def cartesian(self, states=None) -> np.ndarray:
        """[p_x, p_y, v_x, v_y] of ``states`` (default: the estimates), shape (N, 4).

        States with five columns are read as CTRV states and converted; states with four
        columns (a CV filter's estimates) are already Cartesian and returned as a copy.
        """
        s = np.asarray(self.x_hat if states is None else states, dtype=float)
        if s.ndim == 2 and s.shape[1] == 4:
            return s.copy()
        return ctrv_to_cartesian(s)


def cartesian_rmse(estimate_cart, truth_cart) -> dict:
    """RMSE per component of [p_x, p_y, v_x, v_y] arrays (N, 4), as a dict px, py, vx, vy."""
    estimate_cart = as_rows(estimate_cart, "estimate_cart", (4,))
    truth_cart = as_rows(truth_cart, "truth_cart", (4,), len(estimate_cart))
    return dict(zip(("px", "py", "vx", "vy"), (float(e) for e in rmse(estimate_cart, truth_cart, axis=0))))


def _prior(first: Measurement, model: str = "ctrv"):
    """The prior at the first measurement's time, from that measurement alone.

    For CV the same position block, and v_x, v_y each with the CTRV prior's speed σ.
    """
    if first.sensor == "lidar":
        x0, P0 = initial_ctrv_state(first.z, first.R)
    else:
        x0, P0 = initial_ctrv_state(*radar_position_fix(first.z, first.R))
    if model == "ctrv":
        return x0, P0
    x_cv, P_cv = np.zeros(4), np.zeros((4, 4))
    x_cv[:2], P_cv[:2, :2] = x0[:2], P0[:2, :2]
    P_cv[2, 2] = P_cv[3, 3] = P0[2, 2]
    return x_cv, P_cv


#: Lidar observation Jacobian of the CV state [p_x, p_y, v_x, v_y].
_LIDAR_G_CV = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
_LIDAR_G_CV.setflags(write=False)


def fuse_lidar_radar(scenario: CTRVScenario, sigma_a=None, sigma_yaw_acc=None, *, use_lidar=True, use_radar=True,
                     iterated=False, max_iter=20, joseph=True, model="ctrv") -> FusionResult:
    """Reference CTRV EKF (or IEKF) fusing the lidar and radar of a :class:`CTRVScenario`.

    The prior comes from the first measurement alone (:func:`initial_ctrv_state`; a radar
    reading through :func:`radar_position_fix`), which is not fused again. Each later
    measurement is a prediction over its own time step, dt = t_k − t_{k−1} (CTRV, derived
    Jacobians, process noise :math:`B \\, \\mathrm{diag}(\\sigma_a^2, \\sigma_{\\ddot\\psi}^2)
    B^T`; none for dt = 0, two sensors at the same instant), then an update: linear for
    lidar, linearised (or iterated) radar with the wrapped residual. Sensors switched off
    still predict through their rows.

    With ``model="cv"`` the same filter runs the article's constant-velocity model instead:
    state [p_x, p_y, v_x, v_y], noise [a_x, a_y] with σ_a on each axis (``sigma_yaw_acc``
    unused), the radar's h and G of the Cartesian layout; the prior has the same position
    block and v_x, v_y with the CTRV prior's speed variance.

    Parameters
    ----------
    scenario : CTRVScenario
        From :func:`ctrv_lidar_radar` or :func:`read_udacity_log`; rows in time order.
    sigma_a, sigma_yaw_acc : float, optional
        Process noise, m/s² and rad/s²; default the scenario's own values.
    use_lidar, use_radar : bool
        Which sensors to fuse.
    iterated : bool
        Use :func:`~kalman_course.filters.ekf.iekf_update` for the radar.
    max_iter : int
        Its iteration limit.
    joseph : bool
        Joseph form for the covariance updates.
    model : {"ctrv", "cv"}
        The filter's motion model.

    Returns
    -------
    FusionResult

    Raises
    ------
    ValueError
        If the time goes backwards between two rows (the message names both rows and
        times), for a bad process noise or an unknown model.
    """
    if not isinstance(scenario, CTRVScenario):
        raise ValueError(f"scenario must be a CTRVScenario (from ctrv_lidar_radar or read_udacity_log), "
                         f"got {type(scenario).__name__}")
    if model not in ("ctrv", "cv"):
        raise ValueError(f"model must be 'ctrv' or 'cv', got {model!r}")
    max_iter = as_int(max_iter, "max_iter", minimum=1)
    use_lidar, use_radar = as_flag(use_lidar, "use_lidar"), as_flag(use_radar, "use_radar")
    iterated, joseph = as_flag(iterated, "iterated"), as_flag(joseph, "joseph")
    sigma_a = scenario.sigma_a if sigma_a is None else as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_yaw_acc = (scenario.sigma_yaw_acc if sigma_yaw_acc is None
                     else as_scalar(sigma_yaw_acc, "sigma_yaw_acc", allow_zero=True))
    Qw = np.diag([sigma_a**2, sigma_a**2 if model == "cv" else sigma_yaw_acc**2])
    lidar_g, lidar_G = (lidar_observation, LIDAR_G) if model == "ctrv" else (lambda s: s[:2].copy(), _LIDAR_G_CV)
    radar_h = lambda s: symbolic.radar_observation(s, model)
    radar_G = lambda s: symbolic.radar_jacobian(s, model)
    measurements = list(scenario.measurements())
    N, n = len(measurements), (5 if model == "ctrv" else 4)
    xs, Ps, its = np.empty((N, n)), np.empty((N, n, n)), np.ones(N, dtype=int)
    x, P = _prior(measurements[0], model)
    xs[0], Ps[0] = x, P
    for k in range(1, N):
        meas, t_prev = measurements[k], measurements[k - 1].t
        dt = meas.t - t_prev
        if dt < 0:
            raise ValueError(f"scenario.t must not decrease: row {k} ({meas.sensor}) is at t = {meas.t:.6f} s, "
                             f"before row {k - 1} at t = {t_prev:.6f} s")
        if dt > 0:
            x, P = ekf_predict(x, P, lambda s: symbolic.motion_step(model, s, dt),
                               symbolic.motion_jacobian(model, x, dt), Qw,
                               symbolic.motion_noise_jacobian(model, x, dt))
        if meas.sensor == "lidar" and use_lidar:
            x, P = ekf_update(x, P, meas.z, lidar_g, lidar_G, meas.R, joseph=joseph)[:2]
        elif meas.sensor == "radar" and use_radar:
            try:
                if iterated:
                    res = iekf_update(x, P, meas.z, radar_h, radar_G,
                                      meas.R, residual=radar_residual, max_iter=max_iter, joseph=joseph)
                    x, P, its[k] = res.x_hat, res.P_hat, res.iterations
                else:
                    x, P = ekf_update(x, P, meas.z, radar_h, radar_G,
                                      meas.R, residual=radar_residual, joseph=joseph)[:2]
            except ValueError as err:     # e.g. a prior at the radar's position, where its Jacobian has no value
                raise ValueError(f"row {k} (radar, t = {meas.t:.6f} s, predicted position "
                                 f"({x[0]:.3g}, {x[1]:.3g}) m): {err}") from None
        xs[k], Ps[k] = x, P
    truth = scenario.x.copy()
    estimate = ctrv_to_cartesian(xs) if model == "ctrv" else xs
    return FusionResult(scenario.t.copy(), xs, Ps, truth, cartesian_rmse(estimate, ctrv_to_cartesian(truth)), its,
                        model)


# ---------------------------------------------------------------------------------------
# CV against CTRV, like for like, on a truth neither model generated
# ---------------------------------------------------------------------------------------

#: RMSE targets of the Udacity lidar/radar project's rubric, [p_x, p_y, v_x, v_y] (m, m/s).
#: They were set for the project's own data set (filtered there with a CV model), not for
#: the scenarios simulated here.
UDACITY_RUBRIC = (0.11, 0.11, 0.52, 0.52)


def _rmse_row(result: FusionResult) -> np.ndarray:
    return np.array([result.rmse[k] for k in ("px", "py", "vx", "vy")])


@dataclass(frozen=True, eq=False)
class ModelComparison:
    """CV and CTRV filters on the same simulated measurements, each tuned the same way.

    Attributes
    ----------
    seeds : tuple of int
        Seeds of the test scenarios.
    tuning_seeds : tuple of int
        Seeds of the scenarios the process noise was chosen on (disjoint from ``seeds``).
    settings : dict
        model → list of the process-noise settings tried, each a tuple (σ_a, σ_ψ̈) (σ_ψ̈
        unused by CV, given as 0).
    tuning_score : dict
        model → array (len(settings[model]),): median over the tuning seeds of the score
        Σ RMSE_i / target_i over [p_x, p_y, v_x, v_y] (lower is better).
    chosen : dict
        model → the setting with the lowest tuning score.
    rmse : dict
        model → array (len(seeds), 4): RMSE of [p_x, p_y, v_x, v_y] per test seed with the
        chosen setting, m and m/s.
    position_nees : dict
        model → array (len(seeds), N): NEES of the position [p_x, p_y] (2 degrees of
        freedom) at every row of every test run, with the chosen setting.
    rubric : numpy.ndarray, shape (4,)
        The targets the counts compare with (:data:`UDACITY_RUBRIC` by default).
    """

    seeds: tuple
    tuning_seeds: tuple
    settings: dict
    tuning_score: dict
    chosen: dict
    rmse: dict
    position_nees: dict
    rubric: np.ndarray

    def median(self, model: str) -> np.ndarray:
        """Median RMSE over the test seeds, shape (4,)."""
        return np.median(self.rmse[model], axis=0)

    def spread(self, model: str) -> np.ndarray:
        """10th and 90th percentiles of the RMSE over the test seeds, shape (2, 4)."""
        return np.percentile(self.rmse[model], [10, 90], axis=0)

    def meets_rubric(self, model: str) -> np.ndarray:
        """Per test seed, True where all four RMSEs are at or below the rubric, shape (len(seeds),)."""
        return (self.rmse[model] <= self.rubric).all(axis=1)

    def score(self, model: str) -> np.ndarray:
        """Per test seed, Σ RMSE_i / target_i (the tuning score), shape (len(seeds),)."""
        return (self.rmse[model] / self.rubric).sum(axis=1)


def compare_cv_ctrv(seeds=range(20), tuning_seeds=(100, 101), *, scenario=figure_eight_lidar_radar,
                    cv_sigmas=(1.0, 2.0, 4.0, 8.0), ctrv_sigmas=((1.0, 1.0), (3.0, 0.3), (3.0, 1.0), (3.0, 3.0)),
                    rubric=UDACITY_RUBRIC) -> ModelComparison:
    """Tune a CV and a CTRV lidar + radar EKF the same way, then compare them seed by seed.

    Both filters are :func:`fuse_lidar_radar` (same prior position, same updates, same
    Joseph form); only the motion model and its process noise differ. Each model's noise is
    chosen from its own small grid on the tuning scenarios by the same rule: the lowest
    median, over the tuning seeds, of Σ RMSE_i / rubric_i. Then both run, with the chosen
    noise, on the same measurements of every test seed.

    Parameters
    ----------
    seeds : iterable of int
        Seeds of the test scenarios.
    tuning_seeds : iterable of int
        Seeds to tune on; must not overlap ``seeds``.
    scenario : callable
        ``scenario(seed) -> CTRVScenario``; default :func:`figure_eight_lidar_radar`.
    cv_sigmas : iterable of float
        σ_a values (m/s², per axis) tried for CV.
    ctrv_sigmas : iterable of (float, float)
        (σ_a m/s², σ_ψ̈ rad/s²) pairs tried for CTRV.
    rubric : array_like, shape (4,)
        Targets of the score and of :meth:`ModelComparison.meets_rubric`.

    Returns
    -------
    ModelComparison
    """
    seeds = tuple(as_seed(s) for s in seeds)
    tuning_seeds = tuple(as_seed(s) for s in tuning_seeds)
    if not seeds or not tuning_seeds:
        raise ValueError("seeds and tuning_seeds must each hold at least one seed")
    if set(seeds) & set(tuning_seeds):
        raise ValueError(f"tuning_seeds must not overlap seeds; both hold {sorted(set(seeds) & set(tuning_seeds))}")
    rubric = as_vector(rubric, "rubric", 4)
    settings = {"cv": [(as_scalar(s, "cv_sigmas"), 0.0) for s in cv_sigmas],
                "ctrv": [(as_scalar(a, "ctrv_sigmas"), as_scalar(y, "ctrv_sigmas")) for a, y in ctrv_sigmas]}
    if not settings["cv"] or not settings["ctrv"]:
        raise ValueError("cv_sigmas and ctrv_sigmas must each hold at least one setting")
    tuning = [scenario(s) for s in tuning_seeds]

    def run(sc, model, setting):
        return fuse_lidar_radar(sc, sigma_a=setting[0], sigma_yaw_acc=setting[1] or None, model=model)

    tuning_score, chosen, errors, nees = {}, {}, {}, {}
    for model, grid in settings.items():
        tuning_score[model] = np.array([np.median([(_rmse_row(run(sc, model, g)) / rubric).sum() for sc in tuning])
                                        for g in grid])
        chosen[model] = grid[int(np.argmin(tuning_score[model]))]
        errors[model], nees[model] = np.empty((len(seeds), 4)), []
    for i, seed in enumerate(seeds):
        sc = scenario(seed)
        for model in settings:
            res = run(sc, model, chosen[model])
            errors[model][i] = _rmse_row(res)
            nees[model].append(position_nees(res))
    return ModelComparison(seeds, tuning_seeds, settings, tuning_score, chosen, errors,
                           {m: np.array(v) for m, v in nees.items()}, rubric)


def position_nees(result: FusionResult) -> np.ndarray:
    """NEES of the position [p_x, p_y] of a fusion run at every row, shape (N,) (2 dof)."""
    if not isinstance(result, FusionResult):
        raise ValueError(f"result must be a FusionResult (from fuse_lidar_radar), got {type(result).__name__}")
    return nees(result.x_hat[:, :2] - result.truth[:, :2], result.P_hat[:, :2, :2])


# ---------------------------------------------------------------------------------------
# CTRV on KITTI, GNSS at 1 Hz, IMU yaw rate
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


def run_kitti_ctrv(excerpt, *, rate_hz=10.0, sigma_a=3.0, sigma_yaw_acc=0.5, sigma_gyro=0.02,
                   sigma_gnss=None) -> KittiCTRVResult:
    """A CTRV EKF on a KITTI excerpt: noisy 1 Hz GNSS positions and the IMU yaw rate.

    The filter runs at ``rate_hz`` (the IMU decimated): every step predicts with CTRV and
    updates the turn rate ω with the gyro's z reading (σ ``sigma_gyro`` rad/s); at each
    GNSS fix it also updates p_x, p_y (σ = the excerpt's GNSS noise). The prior comes from
    the first two fixes alone: the second fix's position, and speed and heading from the
    difference of the two (with their propagated uncertainty); the filter starts there.

    Parameters
    ----------
    excerpt : KittiExcerpt
        From :func:`kalman_course.data.load_kitti`.
    rate_hz : float
        Filter rate, Hz.
    sigma_a, sigma_yaw_acc : float
        CTRV process noise, m/s² and rad/s².
    sigma_gyro : float
        Noise of the gyro's yaw rate, rad/s.
    sigma_gnss : float, optional
        GNSS noise per axis, m; default the excerpt's.

    Returns
    -------
    KittiCTRVResult
    """
    imu, gnss, truth = excerpt.imu, excerpt.gnss, excerpt.truth
    rate_hz = as_scalar(rate_hz, "rate_hz")
    sigma_a = as_scalar(sigma_a, "sigma_a", allow_zero=True)
    sigma_yaw_acc = as_scalar(sigma_yaw_acc, "sigma_yaw_acc", allow_zero=True)
    sigma_gyro = as_scalar(sigma_gyro, "sigma_gyro")
    sigma_gnss = gnss.sigma if sigma_gnss is None else as_scalar(sigma_gnss, "sigma_gnss")
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
    return KittiCTRVResult(t, xs, Ps, truth_xy, position_rmse(raw, truth_xy[fix_steps]),
                           position_rmse(xs[fix_steps, :2], truth_xy[fix_steps]),
                           position_rmse(xs[:, :2], truth_xy))


# ---------------------------------------------------------------------------------------
# what σ_a is on KITTI: a sweep, and the car's measured accelerations
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class KittiAcceleration:
    """How hard the real car accelerates along its path on one excerpt (OXTS truth).

    Attributes
    ----------
    rms_along : float
        RMS of d|v_h|/dt, the along-track acceleration (|v_h| the horizontal speed), m/s², over the truth poses.
    rms_speed_change : float
        RMS of the change of speed over ``interval`` seconds, m/s, over start times every
        ``step`` seconds.
    interval, step : float
        The interval of ``rms_speed_change`` (the GNSS fix interval) and the filter step, s.
    """

    rms_along: float
    rms_speed_change: float
    interval: float
    step: float

    @property
    def white_equivalent(self) -> float:
        """σ_a of white noise held over steps of ``step`` s that gives the same speed change.

        Over ``interval`` s, n = interval/step independent steps of σ_a add a speed
        variance n (σ_a step)² = σ_a² step · interval, so
        σ_a = rms_speed_change / √(step · interval), m/s².
        """
        return self.rms_speed_change / np.sqrt(self.step * self.interval)


def kitti_acceleration(excerpt, interval: float = 1.0, step: float = 0.1) -> KittiAcceleration:
    """The along-track acceleration of a KITTI excerpt's real trajectory, two ways.

    Parameters
    ----------
    excerpt : KittiExcerpt
        From :func:`kalman_course.data.load_kitti`; uses ``truth`` (real OXTS poses).
    interval : float
        Interval of the speed change, s (1 s: the GNSS fix interval).
    step : float
        Spacing of the start times, s (the CTRV filter's step).

    Returns
    -------
    KittiAcceleration
    """
    interval, step = as_scalar(interval, "interval"), as_scalar(step, "step")
    if not hasattr(excerpt, "truth"):
        raise ValueError(f"excerpt must be a KITTI excerpt with a truth trajectory (load_kitti(name)), "
                         f"got {type(excerpt).__name__}")
    truth = excerpt.truth
    speed = np.hypot(truth.velocity[:, 0], truth.velocity[:, 1])
    along = np.gradient(speed, truth.t)
    starts = np.arange(truth.t[0], truth.t[-1] - interval, step)
    if len(starts) < 2:
        raise ValueError(f"the truth spans {truth.t[-1] - truth.t[0]:.1f} s, too short for interval = {interval} s")
    v0, v1 = truth.interpolate(starts).velocity[:, :2], truth.interpolate(starts + interval).velocity[:, :2]
    change = np.hypot(v1[:, 0], v1[:, 1]) - np.hypot(v0[:, 0], v0[:, 1])
    # root-mean-square of each signal: its RMSE about zero
    return KittiAcceleration(rmse(along, np.zeros_like(along), axis=None), rmse(change, np.zeros_like(change), axis=None),
                             interval, step)


@dataclass(frozen=True, eq=False)
class SigmaSweep:
    """CTRV EKF runs on KITTI excerpts over σ_a values and simulated GNSS draws.

    Every array has shape (len(names), len(sigmas), len(gnss_seeds)).

    Attributes
    ----------
    names : tuple of str
        Excerpt names.
    sigmas : tuple of float
        σ_a values, m/s².
    gnss_seeds : tuple of int
        Seeds of the simulated GNSS noise.
    rmse_all : numpy.ndarray
        Horizontal position RMSE of the filter at every step (``ekf_rmse_all``), m.
    rmse_at_fixes : numpy.ndarray
        The same at the fix times only (``ekf_rmse``), m.
    gnss_rmse : numpy.ndarray
        RMSE of the simulated fixes themselves, m (the same for every σ_a).
    """

    names: tuple
    sigmas: tuple
    gnss_seeds: tuple
    rmse_all: np.ndarray
    rmse_at_fixes: np.ndarray
    gnss_rmse: np.ndarray

    def best_sigma(self) -> np.ndarray:
        """Per excerpt, the σ_a with the lowest median (over the draws) of ``rmse_all``, shape (len(names),)."""
        return np.asarray(self.sigmas)[np.argmin(np.median(self.rmse_all, axis=2), axis=1)]


def kitti_sigma_a_sweep(excerpts, sigmas=(1.0, 3.0, 5.0), gnss_seeds=(1, 2)) -> SigmaSweep:
    """CTRV EKF position RMSE on KITTI excerpts for several σ_a and simulated GNSS draws.

    Each run is :func:`run_kitti_ctrv` with the excerpt's real IMU and truth and 1 Hz GNSS
    fixes re-simulated from the real OXTS positions with
    :func:`kalman_course.data.kitti.simulate_gnss` (σ = the excerpt's GNSS σ) for each seed;
    every σ_a sees the same fixes.

    Parameters
    ----------
    excerpts : sequence of KittiExcerpt
    sigmas : sequence of float
        σ_a values, m/s².
    gnss_seeds : sequence of int
        Seeds of the simulated GNSS noise.

    Returns
    -------
    SigmaSweep
    """
    sigmas = tuple(as_scalar(s, "sigmas") for s in sigmas)
    gnss_seeds = tuple(as_seed(s) for s in gnss_seeds)
    if not sigmas or not gnss_seeds or not len(excerpts):
        raise ValueError("excerpts, sigmas and gnss_seeds must each hold at least one value")
    shape = (len(excerpts), len(sigmas), len(gnss_seeds))
    rmse_all, at_fixes, raw = np.empty(shape), np.empty(shape), np.empty(shape)
    for i, excerpt in enumerate(excerpts):
        for k, seed in enumerate(gnss_seeds):
            noisy = replace(excerpt, gnss=simulate_gnss(excerpt.gnss, seed, excerpt.gnss.sigma))
            for j, sigma in enumerate(sigmas):
                res = run_kitti_ctrv(noisy, sigma_a=sigma)
                rmse_all[i, j, k], at_fixes[i, j, k], raw[i, j, k] = res.ekf_rmse_all, res.ekf_rmse, res.gnss_rmse
    return SigmaSweep(tuple(e.name for e in excerpts), sigmas, gnss_seeds, rmse_all, at_fixes, raw)
